"""Gaussian mixture regression and the fast online GMR (thesis Sec. 4.4-4.5, Alg. 1-2).

GMR conditions a joint Gaussian mixture over ``(x, y)`` on the input ``x``
(Eqs. 4.5-4.8): each component is re-weighted by how well it explains ``x``
(``omega_c = pi_c N(x; mu_cx, Sigma_cx)``, 4.6-4.7) and conditioned by the Gaussian rule
(4.8). The fast online GMR (Alg. 1/2, Sec. 6.2.3) builds that mixture on demand: the ``k``
demonstration points nearest to the query input (thesis: FANN; here an exact
``scipy.spatial.cKDTree``), a 2-component GMM with diagonal covariances fitted to them by
EM (thesis footnote 4 of Ch. 4: diagonal to keep it cheap), then GMR. Choices where the
thesis is silent: docs/decisions.md.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.spatial import cKDTree

_LOG_2PI = float(np.log(2.0 * np.pi))


def _logsumexp(a: np.ndarray, axis: int) -> np.ndarray:
    """log(sum(exp(a))) along axis, keeping it; scipy's is slow on tiny arrays."""
    m = a.max(axis=axis, keepdims=True)
    m = np.where(np.isfinite(m), m, 0.0)
    return m + np.log(np.exp(a - m).sum(axis=axis, keepdims=True))


def gmr(
    weights: np.ndarray,
    means: np.ndarray,
    covariances: np.ndarray,
    x: np.ndarray,
    in_idx: Sequence[int],
    out_idx: Sequence[int],
) -> tuple[np.ndarray, np.ndarray]:
    """Gaussian mixture regression ``p(y | x)`` moment-matched to one Gaussian (4.5-4.8).

    Parameters
    ----------
    weights : numpy.ndarray
        (K,) mixture weights ``pi_c``, summing to 1.
    means : numpy.ndarray
        (K, D) component means of the joint variable.
    covariances : numpy.ndarray
        (K, D, D) full component covariances, or (K, D) diagonal variances.
    x : numpy.ndarray
        (n, i) query inputs (a single (i,) input is accepted).
    in_idx : sequence of int
        (i,) columns of the joint variable that are inputs ``x``.
    out_idx : sequence of int
        (o,) columns that are outputs ``y``.

    Returns
    -------
    mean : numpy.ndarray
        (n, o) conditional means.
    cov : numpy.ndarray
        (n, o, o) conditional covariances.
    """
    w = np.asarray(weights, dtype=float)
    mu = np.asarray(means, dtype=float)
    S = np.asarray(covariances, dtype=float)
    ii = np.asarray(in_idx, dtype=int)
    oo = np.asarray(out_idx, dtype=int)
    X = np.atleast_2d(np.asarray(x, dtype=float))
    K = w.shape[0]
    if S.ndim == 2 and S.shape == mu.shape and w.shape == (K,) and X.shape[1] == ii.size:
        return _gmr_diagonal(w, mu, S, X, ii, oo)
    if S.ndim == 2:
        S = np.einsum("kd,de->kde", S, np.eye(S.shape[1]))
    if mu.shape[0] != K or S.shape[:2] != (K, mu.shape[1]) or S.shape[1] != S.shape[2]:
        raise ValueError(
            f"gmr: inconsistent shapes weights {w.shape}, means {mu.shape}, covariances {S.shape}"
        )
    if X.shape[1] != ii.size:
        raise ValueError(f"gmr: x has {X.shape[1]} columns for {ii.size} input indices")
    mu_x = mu[:, ii]  # (K, i)
    mu_y = mu[:, oo]  # (K, o)
    S_xx = S[:, ii][:, :, ii]  # (K, i, i)
    S_yx = S[:, oo][:, :, ii]  # (K, o, i)
    S_yy = S[:, oo][:, :, oo]  # (K, o, o)
    L = np.linalg.cholesky(S_xx)  # (K, i, i)
    diff = X[None, :, :] - mu_x[:, None, :]  # (K, n, i)
    # Solve L z = diff^T for every component: Mahalanobis terms and S_xx^-1 diff.
    z = np.linalg.solve(L, np.swapaxes(diff, 1, 2))  # (K, i, n)
    maha = np.einsum("kin,kin->kn", z, z)
    logdet = 2.0 * np.log(np.diagonal(L, axis1=1, axis2=2)).sum(axis=1)  # (K,)
    log_px = -0.5 * (maha + logdet[:, None] + ii.size * _LOG_2PI)  # Eq. (4.7)
    log_w = np.log(np.maximum(w, 1e-300))[:, None] + log_px  # Eq. (4.6)
    h = np.exp(log_w - _logsumexp(log_w, axis=0))  # (K, n), 1/z of (4.5)
    Lt_inv_z = np.linalg.solve(np.swapaxes(L, 1, 2), z)  # S_xx^-1 diff^T, (K, i, n)
    mu_cond = mu_y[:, :, None] + np.einsum("koi,kin->kon", S_yx, Lt_inv_z)  # Eq. (4.8)
    A = np.linalg.solve(L, np.swapaxes(S_yx, 1, 2))  # L^-1 S_xy, (K, i, o)
    S_cond = S_yy - np.einsum("kio,kip->kop", A, A)  # Eq. (4.8)
    mean = np.einsum("kn,kon->no", h, mu_cond)
    second = np.einsum("kn,kop->nop", h, S_cond) + np.einsum("kn,kon,kpn->nop", h, mu_cond, mu_cond)
    cov = second - mean[:, :, None] * mean[:, None, :]
    cov = 0.5 * (cov + np.swapaxes(cov, 1, 2))
    return mean, cov


def _gmr_diagonal(
    w: np.ndarray, mu: np.ndarray, var: np.ndarray, X: np.ndarray, ii: np.ndarray, oo: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`gmr` for diagonal covariances: no cross-covariance, so mu_y|x = mu_y (4.8)."""
    v_x = var[:, ii]  # (K, i)
    diff = X[None, :, :] - mu[:, None, ii]  # (K, n, i)
    log_px = -0.5 * (
        (diff * diff / v_x[:, None, :]).sum(axis=2)
        + (np.log(v_x).sum(axis=1) + ii.size * _LOG_2PI)[:, None]
    )  # Eq. (4.7)
    log_w = np.log(np.maximum(w, 1e-300))[:, None] + log_px  # Eq. (4.6)
    h = np.exp(log_w - _logsumexp(log_w, axis=0))  # (K, n), 1/z of (4.5)
    mu_y = mu[:, oo]  # (K, o), Eq. (4.8) with Sigma_yx = 0
    mean = h.T @ mu_y  # (n, o)
    second = np.einsum("kn,ko,kp->nop", h, mu_y, mu_y) + np.einsum(
        "kn,ko,op->nop", h, var[:, oo], np.eye(oo.size)
    )
    cov = second - mean[:, :, None] * mean[:, None, :]
    return mean, 0.5 * (cov + np.swapaxes(cov, 1, 2))


def em_diagonal(
    X: np.ndarray,
    *,
    n_components: int = 2,
    rng: np.random.Generator,
    iters: int = 50,
    reg: float = 1e-3,
    tol: float = 1e-3,
    scale: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """EM for a Gaussian mixture with diagonal covariances (Alg. 1-2, line "EM").

    Parameters
    ----------
    X : numpy.ndarray
        (k, D) data, k >= 1.
    n_components : int
        Requested number of components K (fewer if there are fewer distinct points).
    rng : numpy.random.Generator
        Seeds the k-means++ initialisation.
    iters : int
        Maximum EM iterations.
    reg : float
        Variance floor relative to ``scale``: ``reg * scale`` is added to every variance.
    tol : float
        Stop when the mean log-likelihood per point improves by less than this
        (scikit-learn's ``GaussianMixture`` default).
    scale : numpy.ndarray, optional
        (D,) positive per-column scale [squared data units]; default
        :func:`data_scale` of ``X``.

    Returns
    -------
    weights : numpy.ndarray
        (K,) mixture weights, summing to 1.
    means : numpy.ndarray
        (K, D) component means.
    variances : numpy.ndarray
        (K, D) diagonal variances, each >= ``reg * scale``.
    """
    X = np.asarray(X, dtype=float)
    if X.ndim != 2 or X.shape[0] < 1:
        raise ValueError(f"em_diagonal: expected a non-empty (k, D) array, got {X.shape}")
    if n_components < 1:
        raise ValueError(f"em_diagonal: n_components must be >= 1, got {n_components}")
    k, D = X.shape
    floor = reg * (data_scale(X) if scale is None else np.asarray(scale, dtype=float))
    means = _kmeanspp(X, n_components, rng)
    K = means.shape[0]
    var0 = X.var(axis=0) + floor
    variances = np.tile(var0, (K, 1))
    weights = np.full(K, 1.0 / K)
    if K == 1:
        return np.ones(1), X.mean(axis=0, keepdims=True), var0[None, :]
    X2 = X * X
    const = D * _LOG_2PI
    previous = -np.inf
    for _ in range(iters):
        # E step: log pi_c + log N(x; mu_c, diag var_c), expanded for small matmuls, (k, K).
        prec = 1.0 / variances
        log_p = -0.5 * (
            X2 @ prec.T
            - 2.0 * (X @ (means * prec).T)
            + ((means * means * prec).sum(axis=1) + np.log(variances).sum(axis=1) + const)
        ) + np.log(np.maximum(weights, 1e-300))
        top = log_p.max(axis=1, keepdims=True)
        resp = np.exp(log_p - top)
        total = resp.sum(axis=1, keepdims=True)
        resp /= total
        # M step.
        nk = resp.sum(axis=0) + 10.0 * np.finfo(float).eps
        weights = nk / k
        means = (resp.T @ X) / nk[:, None]
        variances = np.maximum((resp.T @ X2) / nk[:, None] - means * means, 0.0) + floor
        current = float(np.mean(top) + np.mean(np.log(total)))  # mean log-likelihood
        if current - previous < tol:
            break
        previous = current
    return weights, means, variances


def data_scale(X: np.ndarray) -> np.ndarray:
    """Per-column scale of ``X`` (k, D) for a relative variance floor, (D,) > 0.

    The column variance; where it is 0 (to rounding: below 1e-12 of the mean square), the
    column's mean square; where that is 0 too, 1.
    """
    X = np.atleast_2d(np.asarray(X, dtype=float))
    var = X.var(axis=0)
    ms = (X * X).mean(axis=0)
    return np.where(var > 1e-12 * ms, var, np.where(ms > 0, ms, 1.0))


def _kmeanspp(X: np.ndarray, n_components: int, rng: np.random.Generator) -> np.ndarray:
    """k-means++ seeds: up to n_components distinct rows of X, (K, D)."""
    k = X.shape[0]
    centres = [X[rng.integers(k)]]
    d2 = ((X - centres[0]) ** 2).sum(axis=1)
    while len(centres) < n_components:
        total = d2.sum()
        if not total > 0:  # every point coincides with a centre: no more distinct seeds
            break
        nxt = X[rng.choice(k, p=d2 / total)]
        centres.append(nxt)
        d2 = np.minimum(d2, ((X - nxt) ** 2).sum(axis=1))
    return np.array(centres)


class FastOnlineGMR:
    """Fast online GMR over one cluster's demonstration points (Alg. 2, Sec. 6.2.3).

    Parameters
    ----------
    data : numpy.ndarray
        (N, D) joint demonstration points of one motion cluster, N >= 1.
    in_idx : sequence of int
        (i,) input columns (e.g. the target point ``s*``).
    out_idx : sequence of int
        (o,) output columns (e.g. the user command ``u*``).
    k : int
        Nearest neighbours per query (10 in thesis Sec. 7.4.4).
    n_components : int
        Components of the local GMM (2 in the thesis).
    """

    def __init__(
        self,
        data: np.ndarray,
        *,
        in_idx: Sequence[int],
        out_idx: Sequence[int],
        k: int = 10,
        n_components: int = 2,
    ) -> None:
        data = np.asarray(data, dtype=float)
        if data.ndim != 2 or data.shape[0] < 1:
            raise ValueError(
                f"FastOnlineGMR: data must be a non-empty (N, D) array, got {data.shape}"
            )
        if not np.all(np.isfinite(data)):
            raise ValueError("FastOnlineGMR: data must be finite (no NaN or inf)")
        ii = np.asarray(in_idx, dtype=int).reshape(-1)
        oo = np.asarray(out_idx, dtype=int).reshape(-1)
        D = data.shape[1]
        if ii.size < 1 or oo.size < 1:
            raise ValueError("FastOnlineGMR: in_idx and out_idx must be non-empty")
        if np.any((ii < 0) | (ii >= D)) or np.any((oo < 0) | (oo >= D)):
            raise ValueError(f"FastOnlineGMR: column indices must lie in [0, {D})")
        if np.intersect1d(ii, oo).size:
            raise ValueError("FastOnlineGMR: in_idx and out_idx must not overlap")
        if k < 1:
            raise ValueError(f"FastOnlineGMR: k must be >= 1, got {k}")
        self.in_idx = ii
        self.out_idx = oo
        self.k = int(k)
        self.n_components = int(n_components)
        self.data_ = data[:, np.concatenate([ii, oo])].copy()  # (N, i + o), inputs first
        self.scale_ = data_scale(self.data_)  # the cluster's scale, for the variance floor
        self.tree_ = cKDTree(data[:, ii])

    def predict(self, x: np.ndarray, *, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Predict the output for one input: kNN -> EM (diagonal) -> GMR.

        Parameters
        ----------
        x : numpy.ndarray
            (i,) query input.
        rng : numpy.random.Generator
            Seeds the EM initialisation.

        Returns
        -------
        mean : numpy.ndarray
            (o,) predicted output.
        cov : numpy.ndarray
            (o, o) its covariance.
        """
        x = np.asarray(x, dtype=float).reshape(-1)
        i = self.in_idx.size
        if x.size != i:
            raise ValueError(f"FastOnlineGMR: x must have {i} entries, got {x.size}")
        kk = min(self.k, self.data_.shape[0])
        _, idx = self.tree_.query(x, k=kk)  # Alg. 2: nearest neighbours
        local = self.data_[np.atleast_1d(idx)]
        w, mu, var = em_diagonal(  # Alg. 2: EM
            local, n_components=self.n_components, rng=rng, scale=self.scale_
        )
        o = self.out_idx.size
        mean, cov = gmr(w, mu, var, x[None, :], np.arange(i), np.arange(i, i + o))  # Eq. (4.5)
        return mean[0], cov[0]
