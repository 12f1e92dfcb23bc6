"""The fast online GMR of a motion primitive (thesis Alg. 2, Eqs. 4.5-4.8) in the lean
form the contextual mode's rollout needs: the k nearest demonstration points, EM for two
diagonal components from deterministic seeds, and the regression, cached per neighbour
set. Choices: docs/decisions.md.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from autonomy.gmr import data_scale
from autonomy.model import GMR_INPUT


def local_gmm(local: np.ndarray, *, iters: int, reg: float = 1e-3, scale: np.ndarray | None = None):
    """EM for 2 diagonal Gaussian components on a small local set, deterministic seeds.

    Parameters
    ----------
    local : numpy.ndarray
        (k, D) points.
    iters : int
        EM iterations.
    reg : float
        Variance floor relative to ``scale``: ``reg * scale`` is added to every variance.
    scale : numpy.ndarray, optional
        (D,) per-column scale; default :func:`autonomy.gmr.data_scale` of ``local``.

    Returns
    -------
    weights : (K,), means : (K, D), variances : (K, D) with K = 2, or 1 when all points
    coincide.

    Notes
    -----
    Speed (this runs for every new neighbour set of a rollout): the reductions call the
    ufuncs' ``reduce`` directly (the array methods' wrappers cost more than the sums of
    10 x 5 numbers), with the same arithmetic, so the fit is bit for bit that of the plain
    formulation.
    """
    k = local.shape[0]
    add = np.add.reduce
    floor = reg * (data_scale(local) if scale is None else scale)
    centre = add(local, axis=0) / k  # = local.mean(axis=0)
    first = int(add((local - centre) ** 2, axis=1).argmin())
    d2 = add((local - local[first]) ** 2, axis=1)
    second = int(d2.argmax())
    dev = local - add(local, axis=0, keepdims=True) / k
    var0 = add(dev * dev, axis=0) / k  # = local.var(axis=0)
    if not d2[second] > 0:
        return np.ones(1), centre[None, :], (var0 + floor)[None, :]
    mu = local[[first, second]]
    var = np.empty((2, local.shape[1]))
    var[:] = var0 + floor
    log_w = np.array((-math.log(2.0), -math.log(2.0)))
    sq = local * local
    dot = np.dot  # = @ for these 2-D arrays (the same BLAS product), less call overhead
    for _ in range(iters):
        prec = 1.0 / var
        # E step: log pi_c + log N(x; mu_c, diag var_c) up to a constant, (k, 2)
        logp = (dot(local, (mu * prec).T) - 0.5 * dot(sq, prec.T)) + (
            log_w - 0.5 * (add(mu * mu * prec, axis=1) + add(np.log(var), axis=1))
        )
        # the max and the sum over the 2 components as one elementwise operation each
        r = np.exp(logp - np.maximum(logp[:, :1], logp[:, 1:]))
        r /= r[:, :1] + r[:, 1:]
        nk = add(r, axis=0) + 1e-12  # M step
        log_w = np.log(nk / k)
        rt, nkc = r.T, nk[:, None]
        mu = dot(rt, local) / nkc
        var = np.maximum(dot(rt, sq) / nkc - mu * mu, 0.0) + floor
    w = np.exp(log_w)
    return w, mu, var


class LocalGMR:
    """Fast online GMR of one primitive (Alg. 2) with a per-neighbour-set cache.

    Parameters
    ----------
    points : numpy.ndarray
        (N, 5) demonstration points ``(s_x, s_y [m], v_x, v_y, omega)`` of the primitive.
    k : int
        Neighbours per query.
    iters : int
        EM iterations of :func:`local_gmm`.
    cache_size : int
        Local fits kept (cleared when full).
    """

    def __init__(self, points: np.ndarray, *, k: int, iters: int, cache_size: int = 50000):
        self.points_ = np.asarray(points, dtype=float)
        self.scale_ = data_scale(self.points_)  # for the relative variance floor
        self.tree_ = cKDTree(self.points_[:, list(GMR_INPUT)])
        self.k = min(int(k), len(self.points_))
        self.iters = int(iters)
        self.cache_size = int(cache_size)
        self.cache_: dict[bytes, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}
        self.terms_: dict[bytes, tuple[tuple[float, ...], ...]] = {}

    def _key(self, x: Any) -> bytes:
        _, idx = self.tree_.query(x, k=self.k)  # Alg. 2: nearest neighbours
        if self.k == 1:
            idx = np.atleast_1d(np.asarray(idx, dtype=np.intp))
        idx.sort()
        return idx.tobytes()

    def _fit(self, key: bytes):
        fit = self.cache_.get(key)
        if fit is None:
            idx = np.frombuffer(key, dtype=np.intp)
            w, mu, var = local_gmm(self.points_[idx], iters=self.iters, scale=self.scale_)
            fit = (np.log(w), mu[:, :2], var[:, :2], mu[:, 2:])
            if len(self.cache_) >= self.cache_size:
                self.cache_.clear()
                self.terms_.clear()
            self.cache_[key] = fit
        return fit

    def fit_local(self, x: np.ndarray):
        """The local mixture for query ``x`` (2,): (weights, means, variances)."""
        return self._fit(self._key(x))

    def predict(self, x: np.ndarray) -> np.ndarray:
        """Predicted output ``u*`` (3,) for the input ``s*`` (2,) [m] (Eqs. 4.5-4.8)."""
        log_w, mu_x, var_x, mu_y = self.fit_local(x)
        diff = x - mu_x
        logp = log_w - 0.5 * ((diff * diff / var_x).sum(axis=1) + np.log(var_x).sum(axis=1))
        h = np.exp(logp - logp.max())  # Eqs. (4.6), (4.7)
        return (h @ mu_y) / h.sum()  # Eq. (4.8), diagonal: mu_y|x = mu_y

    def predict_xy(self, sx: float, sy: float) -> tuple[float, float, float]:
        """:meth:`predict` for the input ``(sx, sy)`` [m] in scalar arithmetic (the
        rollout's inner loop): the same Eqs. (4.5)-(4.8), per-component constants
        cached with the local fit."""
        key = self._key((sx, sy))
        terms = self.terms_.get(key)
        if terms is None:
            log_w, mu_x, var_x, mu_y = self._fit(key)
            log_det = np.log(var_x).sum(axis=1)
            terms = tuple(
                (
                    float(log_w[c]),
                    float(mu_x[c, 0]),
                    float(mu_x[c, 1]),
                    float(var_x[c, 0]),
                    float(var_x[c, 1]),
                    float(log_det[c]),
                    float(mu_y[c, 0]),
                    float(mu_y[c, 1]),
                    float(mu_y[c, 2]),
                )
                for c in range(len(log_w))
            )
            self.terms_[key] = terms
        logps = []
        for lw, mx, my, vx, vy, ld, *_ in terms:
            dx, dy = sx - mx, sy - my
            logps.append(lw - 0.5 * ((dx * dx / vx + dy * dy / vy) + ld))
        top = max(logps)
        h_sum = o0 = o1 = o2 = 0.0
        for lp, term in zip(logps, terms, strict=True):
            h = math.exp(lp - top)  # Eqs. (4.6), (4.7)
            h_sum += h
            o0 += h * term[6]
            o1 += h * term[7]
            o2 += h * term[8]
        return o0 / h_sum, o1 / h_sum, o2 / h_sum  # Eq. (4.8)
