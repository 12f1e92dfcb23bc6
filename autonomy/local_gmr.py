"""The fast online GMR of a motion primitive (thesis Alg. 2, Eqs. 4.5-4.8) in the lean
form the contextual mode's rollout (Alg. 3) needs at every step: the k nearest
demonstration points, a 2-component diagonal GMM fitted to them by EM run to
convergence, and the regression, cached per neighbour set. Choices: docs/decisions.md.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from autonomy import _kernels
from autonomy.gmr import data_scale
from autonomy.model import GMR_INPUT

EM_TOL = 1e-4  # relative change of the mean log-likelihood at which EM stops
EM_MAX_ITER = 100  # EM iterations at most
_LOG_2PI = math.log(2.0 * math.pi)
_NK_EPS = 1e-12  # added to a component's responsibility sum (an empty component)
POOL_FACTOR = 10  # the kNN search's pool: POOL_FACTOR * k points
POOLS = 16  # pools kept


class LocalMixture(NamedTuple):
    """A fitted local GMM: ``weights`` (K,), ``means`` (K, 5), ``variances`` (K, 5);
    ``n_iter`` EM iterations run (an M and an E step each; 0 for a single component) and
    whether the stopping rule was met (``converged``) rather than the iteration cap."""

    weights: np.ndarray
    means: np.ndarray
    variances: np.ndarray
    n_iter: int
    converged: bool


def check_em_settings(tol: float, max_iter: int) -> None:
    """Raise ValueError unless ``tol`` is a finite number >= 0 and ``max_iter`` an
    integer >= 1 (the stopping rule of :func:`local_gmm`)."""
    if isinstance(tol, bool) or not (isinstance(tol, int | float) and 0.0 <= tol < math.inf):
        raise ValueError(f"tol: must be a finite number >= 0, got {tol!r}")
    if isinstance(max_iter, bool) or not (isinstance(max_iter, int) and max_iter >= 1):
        raise ValueError(f"max_iter: must be an integer >= 1, got {max_iter!r}")


def _m_step(
    stats: list[float], k: int, floor: list[float]
) -> tuple[float, list[float], list[float], list[float]]:
    """M step of one component from its responsibility-weighted sums ``stats`` =
    (sum r x (5), sum r x^2 (5), sum r) over the features ``(x, x^2, 1)`` of the five
    GMR columns, written out column by column.

    Returns its log weight, mean (5,), variance (5,) (floored) and the coefficients
    (11,) of ``log pi + log N(x; mu, diag var)`` on the features (the next E step):
    ``(mu / var, -1 / (2 var), log pi - (sum mu^2 / var + log det + 5 log 2 pi) / 2)``.
    """
    s0, s1, s2, s3, s4, q0, q1, q2, q3, q4, n = stats
    f0, f1, f2, f3, f4 = floor
    nk = n + _NK_EPS
    inv = 1.0 / nk
    m0, m1, m2, m3, m4 = s0 * inv, s1 * inv, s2 * inv, s3 * inv, s4 * inv
    v0, v1, v2 = q0 * inv - m0 * m0, q1 * inv - m1 * m1, q2 * inv - m2 * m2
    v3, v4 = q3 * inv - m3 * m3, q4 * inv - m4 * m4
    v0 = (v0 if v0 > 0.0 else 0.0) + f0
    v1 = (v1 if v1 > 0.0 else 0.0) + f1
    v2 = (v2 if v2 > 0.0 else 0.0) + f2
    v3 = (v3 if v3 > 0.0 else 0.0) + f3
    v4 = (v4 if v4 > 0.0 else 0.0) + f4
    a0, a1, a2, a3, a4 = m0 / v0, m1 / v1, m2 / v2, m3 / v3, m4 / v4
    log_w = math.log(nk / k)
    log_det = math.log(v0) + math.log(v1) + math.log(v2) + math.log(v3) + math.log(v4)
    quad = m0 * a0 + m1 * a1 + m2 * a2 + m3 * a3 + m4 * a4
    const = log_w - 0.5 * (quad + log_det + 5.0 * _LOG_2PI)
    theta = [a0, a1, a2, a3, a4, -0.5 / v0, -0.5 / v1, -0.5 / v2, -0.5 / v3, -0.5 / v4, const]
    return log_w, [m0, m1, m2, m3, m4], [v0, v1, v2, v3, v4], theta


def _em(
    phi: np.ndarray, resp: np.ndarray, floor: list[float], tol: float, max_iter: int
) -> tuple[list[tuple], int, bool]:
    """EM for 2 diagonal components on the features ``phi`` (k, 11) = (x, x^2, 1) from
    the responsibilities ``resp`` (2, k) of an initial partition.

    An iteration is an M step and an E step, which also gives the mean log-likelihood of
    the new parameters; EM stops when that changes by less than ``tol`` relative to it
    (Bishop 2006, Sec. 9.2.2, step 4) or after ``max_iter`` iterations. Returns
    [(log w, mu, var, E-step coefficients)] per component, the iterations run and
    whether the stopping rule was met.
    """
    k = phi.shape[0]
    phi_t = phi.T
    previous = math.nan
    for it in range(1, max_iter + 1):
        s0, s1 = np.dot(resp, phi).tolist()  # M step
        p0, p1 = _m_step(s0, k, floor), _m_step(s1, k, floor)
        params = [p0, p1]
        logp = np.dot((p0[3], p1[3]), phi_t)  # E step, (2, k): log pi_c N(x_i; mu_c, var_c)
        lse = np.logaddexp(logp[0], logp[1])  # (k,) log sum_c pi_c N(x_i; mu_c, var_c)
        current = math.fsum(lse.tolist()) / k  # mean log-likelihood
        if abs(current - previous) < tol * abs(current):
            return params, it, True
        if it < max_iter:
            resp = np.exp(np.subtract(logp, lse, out=logp), out=logp)  # (2, k)
            previous = current
    return params, max_iter, False


def _features(x: np.ndarray) -> np.ndarray:
    """The features (k, 11) = (x, x^2, 1) of points ``x`` (k, 5)."""
    return np.concatenate((x, x * x, np.ones((len(x), 1))), axis=1)


def _fit(
    phi: np.ndarray, floor: list[float], tol: float, max_iter: int
) -> tuple[list[tuple], int, bool]:
    """:func:`local_gmm` on the features ``phi`` (k, 11) of points ``x`` relative to any
    origin (:func:`_features`), with the variance floor (5,). Returns the components
    [(log w, mu, var, _)] with ``mu`` relative to that origin, the iterations and
    whether EM converged."""
    k = phi.shape[0]
    x = phi[:, :5]
    gram = np.dot(x, x.T).tolist()  # (k, k)
    # |x_i - m|^2 = |x_i|^2 - 2 x_i . m + |m|^2, m the mean: the last term is common
    to_mean = [row[i] - 2.0 * sum(row) / k for i, row in enumerate(gram)]
    first = to_mean.index(min(to_mean))  # seed: the point nearest the mean
    g, gf = gram[first], gram[first][first]
    d0 = [row[i] + gf - 2.0 * b for i, (row, b) in enumerate(zip(gram, g, strict=True))]
    second = d0.index(max(d0))  # seed: the point farthest from that one
    if not d0[second] > 0.0:  # all points coincide: one component
        return [(0.0, phi[0, :5].tolist(), floor, None)], 0, True
    g, gs = gram[second], gram[second][second]
    near = [
        float(row[i] + gs - 2.0 * b < c)
        for i, (row, b, c) in enumerate(zip(gram, g, d0, strict=True))
    ]
    resp = np.array((*[1.0 - n for n in near], *near)).reshape(2, k)  # the nearer seed
    return _em(phi, resp, floor, tol, max_iter)


def local_gmm(
    local: np.ndarray,
    *,
    tol: float = EM_TOL,
    max_iter: int = EM_MAX_ITER,
    reg: float = 1e-3,
    scale: np.ndarray | None = None,
    origin: np.ndarray | None = None,
) -> LocalMixture:
    """A 2-component diagonal GMM fitted by EM to a small local set (Alg. 2, "EM").

    Deterministic: the seeds are the point nearest the set's mean and the point farthest
    from that one; EM starts from the partition of the points by the nearer seed (ties
    to the first), i.e. from that partition's M step (weights, means, variances), and
    runs until the mean log-likelihood per point changes by less than ``tol`` relative
    to its value, or ``max_iter`` times.

    Parameters
    ----------
    local : numpy.ndarray
        (k, 5) points, the GMR columns ``(s_x, s_y [m], v_x, v_y, omega)``.
    tol : float
        Relative tolerance of the stopping rule, >= 0 (0: always ``max_iter``
        iterations).
    max_iter : int
        Iteration cap, >= 1.
    reg : float
        Variance floor relative to ``scale``: ``reg * scale`` is added to every variance.
    scale : numpy.ndarray, optional
        (5,) per-column scale; default :func:`autonomy.gmr.data_scale` of ``local``.
    origin : numpy.ndarray, optional
        (5,) the origin of the sums EM accumulates (a point near the data keeps them well
        conditioned); default the mean of ``local``. It changes the fit by rounding only.

    Returns
    -------
    LocalMixture
        K = 2 components, or K = 1 (``n_iter`` 0) when all points coincide.
    """
    check_em_settings(tol, max_iter)
    local = np.asarray(local, dtype=float)
    if local.ndim != 2 or local.shape[1] != 5 or len(local) < 1:
        raise ValueError(f"local: must be a non-empty (k, 5) array, got {local.shape}")
    floor = reg * (data_scale(local) if scale is None else np.asarray(scale, dtype=float))
    origin = local.mean(axis=0) if origin is None else np.asarray(origin, dtype=float)
    params, n_iter, converged = _fit(_features(local - origin), floor.tolist(), tol, max_iter)
    log_w, mu, var = (np.array(v, dtype=float) for v in list(zip(*params, strict=True))[:3])
    return LocalMixture(np.exp(log_w), mu + origin, var, n_iter, converged)


class _FitCache:
    """The local fits of :class:`LocalGMR` by neighbour set, as arrays a kernel reads:
    an open-addressing table of ``keys`` (cap, k) sorted neighbour indices, ``vals``
    (cap, 18) per-component terms (see :meth:`LocalGMR._terms`), ``used`` (cap,) the
    number of components (0: empty); ``ist[1]`` entries (``ist`` is shared with the
    pools). Cleared when ``size`` entries are stored and another comes."""

    def __init__(self, k: int, size: int, ist: np.ndarray) -> None:
        self.size, self.ist = size, ist
        self._alloc(k, 1024)

    def _alloc(self, k: int, cap: int) -> None:
        self.keys = np.zeros((cap, k), dtype=np.int64)
        self.vals = np.zeros((cap, 18))
        self.used = np.zeros(cap, dtype=np.int64)

    def __len__(self) -> int:
        return int(self.ist[1])

    def reserve(self, n: int) -> None:
        """Room for ``n`` more entries at a load of at most one half."""
        cap = len(self.used)
        if 2 * (min(int(self.ist[1]), self.size) + n) <= cap:
            return
        old = (self.keys, self.vals, self.used)
        while 2 * (min(int(self.ist[1]), self.size) + n) > cap:
            cap *= 2
        self._alloc(self.keys.shape[1], cap)
        _kernels.cache_rehash(*old, self.keys, self.vals, self.used, self.ist)


class LocalGMR:
    """Fast online GMR of one primitive (Alg. 2) with a per-neighbour-set cache.

    The state (kNN pools, fit cache, counts) lives in arrays that the compiled rollout
    (:func:`autonomy._kernels.rollout_kernel`) reads and updates; the methods here give
    the same answers one query at a time.

    Parameters
    ----------
    points : numpy.ndarray
        (N, 5) demonstration points ``(s_x, s_y [m], v_x, v_y, omega)`` of the primitive.
    k : int
        Neighbours per query.
    tol, max_iter :
        EM's stopping rule (:func:`local_gmm`).
    cache_size : int
        Local fits kept (cleared when full).

    Attributes
    ----------
    n_iter_counts_ : numpy.ndarray
        (max_iter + 1,) int64, number of local fits made with each EM iteration count.
    """

    def __init__(
        self,
        points: np.ndarray,
        *,
        k: int,
        tol: float = EM_TOL,
        max_iter: int = EM_MAX_ITER,
        cache_size: int = 50000,
    ):
        check_em_settings(tol, max_iter)
        self.points_ = np.asarray(points, dtype=float)
        if self.points_.ndim != 2 or self.points_.shape[1] != 5 or len(self.points_) < 1:
            raise ValueError(f"points: must be a non-empty (N, 5) array, got {self.points_.shape}")
        if isinstance(k, bool) or not (isinstance(k, int | np.integer) and k >= 1):
            raise ValueError(f"k: must be an integer >= 1, got {k!r}")
        self.scale_ = data_scale(self.points_)  # for the relative variance floor
        self.floor_ = (1e-3 * self.scale_).tolist()  # as local_gmm's default reg
        self.inputs_ = np.ascontiguousarray(self.points_[:, list(GMR_INPUT)])  # (N, 2) [m]
        self.tree_ = cKDTree(self.inputs_)  # for callers; the pools are found by brute force
        self.k = min(int(k), len(self.points_))
        self.tol = float(tol)
        self.max_iter = max_iter
        self.cache_size = int(cache_size)
        self.n_iter_counts_ = np.zeros(max_iter + 1, dtype=np.int64)
        self.pool_size = min(POOL_FACTOR * self.k, len(self.points_))
        self.origin_ = self.points_.mean(axis=0)  # (5,) origin of the local fits' sums
        self.features_ = np.ascontiguousarray(_features(self.points_ - self.origin_))  # (N, 11)
        # the last POOLS pools (see _key): centre x, y and radius [m]; the indices of the
        # pool_size points; (p - c, |p - c|^2) of each; the slots, most recent first
        self._meta = np.zeros((POOLS, 3))
        self._pidx = np.zeros((POOLS, self.pool_size), dtype=np.int64)
        self._prel = np.zeros((POOLS, self.pool_size, 3))
        self._lru = np.zeros(POOLS, dtype=np.int64)
        self._ist = np.zeros(2, dtype=np.int64)  # pools kept, fits cached
        self.cache_ = _FitCache(self.k, self.cache_size, self._ist)

    def kernel_state(self) -> tuple:
        """The arrays and settings :func:`autonomy._kernels.rollout_kernel` takes."""
        c = self.cache_
        return (
            self.k,
            self.inputs_,
            self.features_,
            self.origin_,
            np.asarray(self.floor_, dtype=float),
            self.tol,
            self.max_iter,
            self.cache_size,
            self._meta,
            self._pidx,
            self._prel,
            self._lru,
            self._ist,
            c.keys,
            c.vals,
            c.used,
            self.n_iter_counts_,
        )

    def _key(self, sx: float, sy: float) -> bytes:
        """The sorted indices of the ``k`` points nearest ``(sx, sy)`` (Alg. 2), as bytes.

        Searched by brute force among a pool, the ``pool_size`` points nearest an earlier
        query ``c`` (every point within ``radius`` of it), when that is exact: when the
        k-th nearest pool point lies closer than ``radius - |q - c|``, every point outside
        the pool is farther. The last ``POOLS`` pools are kept (a rollout starts near
        where the previous one started); without one that answers, a pool is fetched
        around ``q`` (:meth:`fetch_pool`).
        """
        near = np.empty(self.k, dtype=np.int64)
        args = (self._meta, self._pidx, self._prel, self._lru, self._ist, near)
        if not _kernels.pool_search(float(sx), float(sy), self.k, *args):
            near = self.fetch_pool(float(sx), float(sy))
        return near.astype(np.intp).tobytes()

    def fetch_pool(self, sx: float, sy: float) -> np.ndarray:
        """Fetch the pool around ``(sx, sy)`` (the ``pool_size`` nearest points, as a
        cKDTree query would give them, :func:`autonomy._kernels.fetch_pool`), keep it as
        the most recent (dropping the oldest beyond ``POOLS``); returns the ``k`` nearest
        (sorted, int64)."""
        near = np.empty(self.k, dtype=np.int64)
        args = (self._meta, self._pidx, self._prel, self._lru, self._ist, near)
        _kernels.fetch_pool(float(sx), float(sy), self.inputs_, self.k, *args)
        return near

    def _terms(self, key: bytes) -> tuple[tuple[float, ...], ...]:
        """The local fit of the neighbour set ``key`` as per-component constants of
        Eqs. (4.6)-(4.8): (log w, the input means (2) and variances (2) [m, m^2], the
        log determinant of the input covariance, the output means ``u*`` (3))."""
        near = np.frombuffer(key, dtype=np.intp).astype(np.int64)
        self.cache_.reserve(1)
        c = self.cache_
        row = _kernels.local_terms(
            near,
            *self.kernel_state()[2:8],
            c.keys,
            c.vals,
            c.used,
            self._ist,
            self.n_iter_counts_,
        )
        terms = self.cache_.vals[row].tolist()
        return tuple(tuple(terms[9 * c : 9 * c + 9]) for c in range(self.cache_.used[row]))

    def fit_local(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The local mixture for query ``x`` (2,) [m]: log weights (K,), input means and
        variances (K, 2), output means (K, 3)."""
        t = np.array(self._terms(self._key(float(x[0]), float(x[1]))))
        return t[:, 0], t[:, 1:3], t[:, 3:5], t[:, 6:]

    def predict(self, x: np.ndarray) -> np.ndarray:
        """Predicted output ``u*`` (3,) for the input ``s*`` (2,) [m] (Eqs. 4.5-4.8)."""
        log_w, mu_x, var_x, mu_y = self.fit_local(x)
        diff = np.asarray(x, dtype=float) - mu_x
        logp = log_w - 0.5 * ((diff * diff / var_x).sum(axis=1) + np.log(var_x).sum(axis=1))
        h = np.exp(logp - logp.max())  # Eqs. (4.6), (4.7)
        return (h @ mu_y) / h.sum()  # Eq. (4.8), diagonal: mu_y|x = mu_y

    def predict_xy(self, sx: float, sy: float) -> tuple[float, float, float]:
        """:meth:`predict` for the input ``(sx, sy)`` [m] in scalar arithmetic (the
        rollout's inner loop): the same Eqs. (4.5)-(4.8)."""
        terms = self._terms(self._key(sx, sy))
        if len(terms) == 1:
            return terms[0][6:]
        (lw0, mx0, my0, vx0, vy0, ld0, a0, b0, c0), (lw1, mx1, my1, vx1, vy1, ld1, a1, b1, c1) = (
            terms
        )
        dx0, dy0, dx1, dy1 = sx - mx0, sy - my0, sx - mx1, sy - my1
        l0 = lw0 - 0.5 * ((dx0 * dx0 / vx0 + dy0 * dy0 / vy0) + ld0)  # Eqs. (4.6), (4.7)
        l1 = lw1 - 0.5 * ((dx1 * dx1 / vx1 + dy1 * dy1 / vy1) + ld1)
        if l0 >= l1:
            h0, h1 = 1.0, math.exp(l1 - l0)
        else:
            h0, h1 = math.exp(l0 - l1), 1.0
        h = h0 + h1
        return (h0 * a0 + h1 * a1) / h, (h0 * b0 + h1 * b1) / h, (h0 * c0 + h1 * c1) / h
