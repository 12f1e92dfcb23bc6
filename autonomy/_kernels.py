"""Compiled kernels of the contextual mode's step (issue 25): the fast online GMR of
:mod:`autonomy.local_gmr` (pooled kNN, local EM, prediction; thesis Alg. 2) and the
rollout of :mod:`autonomy.contextual` (Alg. 3); the rest of the tick's kernels are in
:mod:`autonomy._tick_kernels`.

Every kernel repeats the floating-point operations of the Python/numpy code it replaces
in the same order, so its results are bit-identical to it (tests/test_contextual_kernels.py
compares them). Where that code called BLAS or CPython, the kernel reproduces what those
compute on this platform (OpenBLAS's Haswell kernels, numpy 2.4, CPython 3.11):

- a small matrix product (OpenBLAS ``dgemm``/``dsyrk``) is a chain of fused multiply-adds
  over the inner index, in order, from 0 (:func:`fma`);
- ``(P, 3) @ (3,)`` (OpenBLAS ``dgemv_t``, P >= 2) is ``0 + fma(a2, q2, fma(a0, q0, a1 q1))``,
  and for P = 1 (``ddot``) the plain sum ``((0 + a0 q0) + a1 q1) + a2 q2``;
- ``math.hypot`` is CPython's own correctly rounded norm (:func:`py_hypot`), not libm's;
- ``math.fsum`` is Shewchuk's exact summation as CPython implements it (:func:`fsum`);
- ``numpy.logaddexp`` and ``numpy.exp`` of float64 are libm's ``exp``/``log1p`` per element
  (numpy 2.4 has no AVX2 float64 ``exp``), as ``math`` is in a kernel.

Kernels take contiguous float64/int64 arrays and scalars; ``@njit(cache=True)``, no
fastmath (numba does not fuse ``a * b + c`` unless asked, checked by the tests).
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import njit
from numba.core import types
from numba.extending import intrinsic

_LOG_2PI = math.log(2.0 * math.pi)
_NK_EPS = 1e-12  # as autonomy.local_gmr
_LOGE2 = math.log(2.0)  # numpy's NPY_LOGE2
_DBL_MIN = 2.2250738585072014e-308


@intrinsic
def _fma(typingctx, a, b, c):
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        d = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [d], ir.FunctionType(d, [d, d, d]))
        return builder.call(fn, args)

    return sig, codegen


@njit(cache=True)
def fma(a: float, b: float, c: float) -> float:
    """``a * b + c`` rounded once (the FMA instruction BLAS kernels use)."""
    return _fma(a, b, c)


@njit(cache=True)
def py_hypot(x: float, y: float) -> float:
    """CPython's ``math.hypot(x, y)`` (``vector_norm`` of Modules/mathmodule.c): the
    squares summed in double length, one differential correction of the square root."""
    ax, ay = abs(x), abs(y)
    big = 0.0
    if ax > big:
        big = ax
    if ay > big:
        big = ay
    if math.isinf(big):
        return big
    if math.isnan(x) or math.isnan(y):
        return math.nan
    if big == 0.0:
        return big
    unscale = 1.0
    _, e = math.frexp(big)
    if e < -1023:  # subnormal: CPython rescales by DBL_MIN first
        ax, ay, big, unscale = ax / _DBL_MIN, ay / _DBL_MIN, big / _DBL_MIN, _DBL_MIN
        _, e = math.frexp(big)
    scale = math.ldexp(1.0, -e)
    csum, frac1, frac2 = 1.0, 0.0, 0.0
    for v in (ax, ay):
        v *= scale
        hi = v * v
        lo = fma(v, v, -hi)
        s = csum + hi
        frac2 += (csum - s) + hi
        csum = s
        frac1 += lo
    h = math.sqrt(csum - 1.0 + (frac1 + frac2))
    hi = -h * h
    lo = fma(-h, h, -hi)
    s = csum + hi
    frac2 += (csum - s) + hi
    csum = s
    frac1 += lo
    v = csum - 1.0 + (frac1 + frac2)
    h += v / (2.0 * h)
    return unscale * (h / scale)


@njit(cache=True)
def fsum(values: np.ndarray, n: int) -> float:
    """CPython's ``math.fsum`` of ``values[:n]`` (finite values; NaN if any is not)."""
    partials = np.empty(n + 1)
    m = 0
    for t in range(n):
        x = values[t]
        if not math.isfinite(x):
            return math.nan
        i = 0
        for j in range(m):
            y = partials[j]
            if abs(x) < abs(y):
                x, y = y, x
            hi = x + y
            lo = y - (hi - x)
            if lo != 0.0:
                partials[i] = lo
                i += 1
            x = hi
        m = i
        if x != 0.0:
            partials[m] = x
            m += 1
    hi = 0.0
    lo = 0.0
    if m > 0:
        m -= 1
        hi = partials[m]
        while m > 0:
            x = hi
            m -= 1
            y = partials[m]
            hi = x + y
            yr = hi - x
            lo = y - yr
            if lo != 0.0:
                break
        if m > 0 and ((lo < 0.0 and partials[m - 1] < 0.0) or (lo > 0.0 and partials[m - 1] > 0.0)):
            y = lo * 2.0
            x = hi + y
            yr = x - hi
            if y == yr:
                hi = x
    return hi


@njit(cache=True)
def logaddexp(x: float, y: float) -> float:
    """numpy's ``logaddexp`` of two float64 (npy_logaddexp)."""
    if x == y:
        return x + _LOGE2
    tmp = x - y
    if tmp > 0:
        return x + math.log1p(math.exp(-tmp))
    if tmp <= 0:
        return y + math.log1p(math.exp(tmp))
    return tmp


@njit(cache=True)
def dot3(a0: float, a1: float, a2: float, q0: float, q1: float, q2: float, rows: int) -> float:
    """One entry of numpy's ``A @ q`` for ``A`` (rows, 3) C-contiguous, ``q`` (3,)."""
    if rows == 1:
        return ((0.0 + a0 * q0) + a1 * q1) + a2 * q2
    return 0.0 + fma(a2, q2, fma(a0, q0, a1 * q1))


# --------------------------------------------------------------------------- local EM


@njit(cache=True)
def _m_step(s: np.ndarray, c: int, k: int, floor: np.ndarray, mu, var, theta) -> float:
    """autonomy.local_gmr._m_step of component ``c`` from its sums ``s[c]`` (11,): writes
    ``mu[c]``, ``var[c]`` (5,) and the E-step coefficients ``theta[c]`` (11,); returns
    the log weight."""
    nk = s[c, 10] + _NK_EPS
    inv = 1.0 / nk
    log_det = 0.0
    quad = 0.0
    for f in range(5):
        m = s[c, f] * inv
        v = s[c, 5 + f] * inv - m * m
        v = (v if v > 0.0 else 0.0) + floor[f]
        a = m / v
        mu[c, f], var[c, f], theta[c, f], theta[c, 5 + f] = m, v, a, -0.5 / v
    log_w = math.log(nk / k)
    # the Python sums run left to right: log v0 + log v1 + ..., m0 a0 + m1 a1 + ...
    log_det = math.log(var[c, 0]) + math.log(var[c, 1])
    log_det = log_det + math.log(var[c, 2])
    log_det = log_det + math.log(var[c, 3])
    log_det = log_det + math.log(var[c, 4])
    quad = mu[c, 0] * theta[c, 0] + mu[c, 1] * theta[c, 1]
    quad = quad + mu[c, 2] * theta[c, 2]
    quad = quad + mu[c, 3] * theta[c, 3]
    quad = quad + mu[c, 4] * theta[c, 4]
    theta[c, 10] = log_w - 0.5 * (quad + log_det + 5.0 * _LOG_2PI)
    return log_w


@njit(cache=True)
def _em(phi, resp, floor, tol, max_iter, lw, mu, var) -> int:
    """autonomy.local_gmr._em on ``phi`` (k, 11) from ``resp`` (2, k): writes the log
    weights ``lw`` (2,), means ``mu`` and variances ``var`` (2, 5); returns the
    iterations run."""
    k = phi.shape[0]
    s = np.empty((2, 11))
    theta = np.empty((2, 11))
    logp = np.empty((2, k))
    lse = np.empty(k)
    previous = math.nan
    for it in range(1, max_iter + 1):
        for c in range(2):  # M step: resp @ phi, BLAS order
            for f in range(11):
                acc = 0.0
                for i in range(k):
                    acc = fma(resp[c, i], phi[i, f], acc)
                s[c, f] = acc
        for c in range(2):
            lw[c] = _m_step(s, c, k, floor, mu, var, theta)
        for i in range(k):  # E step: theta @ phi.T, BLAS order
            for c in range(2):
                acc = 0.0
                for f in range(11):
                    acc = fma(theta[c, f], phi[i, f], acc)
                logp[c, i] = acc
            lse[i] = logaddexp(logp[0, i], logp[1, i])
        current = fsum(lse, k) / k
        if abs(current - previous) < tol * abs(current):
            return it
        if it < max_iter:
            for i in range(k):
                resp[0, i] = math.exp(logp[0, i] - lse[i])
                resp[1, i] = math.exp(logp[1, i] - lse[i])
            previous = current
    return max_iter


@njit(cache=True)
def fit(phi, floor, tol, max_iter, lw, mu, var) -> tuple[int, int]:
    """autonomy.local_gmr._fit on the features ``phi`` (k, 11): writes ``lw`` (K,),
    ``mu``, ``var`` (K, 5) relative to the features' origin; returns (K, iterations)."""
    k = phi.shape[0]
    gram = np.empty((k, k))  # x @ x.T (BLAS dsyrk order)
    for i in range(k):
        for j in range(k):
            acc = 0.0
            for f in range(5):
                acc = fma(phi[i, f], phi[j, f], acc)
            gram[i, j] = acc
    first, best = 0, 0.0
    for i in range(k):
        total = 0.0
        for j in range(k):
            total += gram[i, j]
        to_mean = gram[i, i] - 2.0 * total / k
        if i == 0 or to_mean < best:
            first, best = i, to_mean
    d0 = np.empty(k)
    gf = gram[first, first]
    second = 0
    for i in range(k):
        d0[i] = gram[i, i] + gf - 2.0 * gram[first, i]
        if i == 0 or d0[i] > d0[second]:
            second = i
    if not d0[second] > 0.0:  # all points coincide: one component
        lw[0] = 0.0
        for f in range(5):
            mu[0, f], var[0, f] = phi[0, f], floor[f]
        return 1, 0
    gs = gram[second, second]
    resp = np.empty((2, k))
    for i in range(k):
        near = 1.0 if gram[i, i] + gs - 2.0 * gram[second, i] < d0[i] else 0.0
        resp[0, i], resp[1, i] = 1.0 - near, near
    return 2, _em(phi, resp, floor, tol, max_iter, lw, mu, var)


# --------------------------------------------------------------------------- kNN, cache


@njit(cache=True)
def pool_search(sx, sy, k, meta, pidx, prel, lru, ist, near) -> bool:
    """autonomy.local_gmr.LocalGMR._key's search of the kept pools (LRU order ``lru``,
    ``ist[0]`` of them): True and the sorted neighbour indices in ``near`` (k,) when a
    pool answers exactly (then moved to the front), else False."""
    rows = pidx.shape[1]
    bd = np.empty(k)
    bi = np.empty(k, dtype=np.int64)
    for n in range(ist[0]):
        slot = lru[n]
        dx, dy = sx - meta[slot, 0], sy - meta[slot, 1]
        margin = meta[slot, 2] - py_hypot(dx, dy)
        if margin > 0.0:
            q0, q1 = -2.0 * dx, -2.0 * dy
            m = 0  # the k smallest d2 (p - c).(q - c) terms, ties by index (stable argsort)
            for p in range(rows):
                d = dot3(prel[slot, p, 0], prel[slot, p, 1], prel[slot, p, 2], q0, q1, 1.0, rows)
                if m < k:
                    pos = m
                    m += 1
                elif d < bd[k - 1]:
                    pos = k - 1
                else:
                    continue
                while pos > 0 and d < bd[pos - 1]:
                    bd[pos], bi[pos] = bd[pos - 1], bi[pos - 1]
                    pos -= 1
                bd[pos], bi[pos] = d, p
            if bd[k - 1] + (dx * dx + dy * dy) < margin * margin:
                for t in range(n, 0, -1):
                    lru[t] = lru[t - 1]
                lru[0] = slot
                for t in range(k):
                    near[t] = pidx[slot, bi[t]]
                near.sort()
                return True
    return False


@njit(cache=True)
def fetch_pool(sx, sy, inputs, k, meta, pidx, prel, lru, ist, near) -> None:
    """autonomy.local_gmr.LocalGMR's pool fetch: the ``P = pidx.shape[1]`` points of
    ``inputs`` (N, 2) [m] nearest ``(sx, sy)``, nearest first (ties by index), found by
    brute force with the distances the cKDTree computed (``dx dx + dy dy``; the same order
    and radius as its ``query``), kept as the most recent pool (the oldest of ``POOLS``
    dropped); their ``k`` nearest (sorted) into ``near``."""
    n, rows = inputs.shape[0], pidx.shape[1]
    bd = np.empty(rows)
    bi = np.empty(rows, dtype=np.int64)
    for t in range(n):
        dx, dy = inputs[t, 0] - sx, inputs[t, 1] - sy
        d = dx * dx + dy * dy
        if t < rows:
            pos = t
        elif d < bd[rows - 1]:
            pos = rows - 1
        else:
            continue
        while pos > 0 and d < bd[pos - 1]:
            bd[pos], bi[pos] = bd[pos - 1], bi[pos - 1]
            pos -= 1
        bd[pos], bi[pos] = d, t
    pools = lru.shape[0]
    slot = ist[0] if ist[0] < pools else lru[pools - 1]
    ist[0] = min(ist[0] + 1, pools)
    for t in range(pools - 1, 0, -1):
        lru[t] = lru[t - 1]
    lru[0] = slot
    meta[slot, 0], meta[slot, 1] = sx, sy
    meta[slot, 2] = math.inf if rows == n else math.sqrt(bd[rows - 1])
    for p in range(rows):
        pidx[slot, p] = bi[p]
        rx, ry = inputs[bi[p], 0] - sx, inputs[bi[p], 1] - sy
        prel[slot, p, 0], prel[slot, p, 1], prel[slot, p, 2] = rx, ry, rx * rx + ry * ry
    near[:] = bi[:k]
    near.sort()


@njit(cache=True)
def _slot(near, keys) -> int:
    """Hash slot of the sorted neighbour indices ``near`` in a table of ``len(keys)``
    (a power of two) rows."""
    h = np.uint64(1469598103934665603)
    for v in near:
        h = (h ^ np.uint64(v)) * np.uint64(1099511628211)
    return np.int64(h & np.uint64(len(keys) - 1))


@njit(cache=True)
def cache_put(near, terms, ncomp, keys, vals, used, ist) -> None:
    """Store ``terms`` (ncomp * 9,) under ``near`` (open addressing; ``ist[1]`` entries)."""
    i = _slot(near, keys)
    while used[i]:
        i = (i + 1) & (len(keys) - 1)
    keys[i, :] = near
    vals[i, : ncomp * 9] = terms[: ncomp * 9]
    used[i] = ncomp
    ist[1] += 1


@njit(cache=True)
def cache_get(near, keys, vals, used) -> int:
    """Row of ``near`` in the fit cache, -1 if absent."""
    i = _slot(near, keys)
    while used[i]:
        same = True
        for t in range(len(near)):
            if keys[i, t] != near[t]:
                same = False
                break
        if same:
            return i
        i = (i + 1) & (len(keys) - 1)
    return -1


@njit(cache=True)
def local_terms(
    near, features, origin, floor, tol, max_iter, cache_size, keys, vals, used, ist, counts
):
    """autonomy.local_gmr.LocalGMR._terms: the cached or new local fit of the neighbour
    set ``near`` (sorted, k); returns its row of ``vals`` (per component: log w, input
    means (2), variances (2), log det, output means (3))."""
    row = cache_get(near, keys, vals, used)
    if row >= 0:
        return row
    k = len(near)
    phi = np.empty((k, 11))
    for i in range(k):
        phi[i, :] = features[near[i]]
    lw, mu, var = np.empty(2), np.empty((2, 5)), np.empty((2, 5))
    ncomp, n_iter = fit(phi, floor, tol, max_iter, lw, mu, var)
    counts[n_iter] += 1
    terms = np.empty(18)
    for c in range(ncomp):
        t = terms[9 * c : 9 * c + 9]
        t[0], t[1], t[2] = lw[c], mu[c, 0] + origin[0], mu[c, 1] + origin[1]
        t[3], t[4], t[5] = var[c, 0], var[c, 1], math.log(var[c, 0] * var[c, 1])
        t[6], t[7], t[8] = mu[c, 2] + origin[2], mu[c, 3] + origin[3], mu[c, 4] + origin[4]
    if ist[1] >= cache_size:
        used[:] = 0
        ist[1] = 0
    cache_put(near, terms, ncomp, keys, vals, used, ist)
    return cache_get(near, keys, vals, used)


@njit(cache=True)
def predict_terms(t, ncomp, sx, sy) -> tuple[float, float, float]:
    """autonomy.local_gmr.LocalGMR.predict_xy from a fit's terms ``t`` (Eqs. 4.5-4.8)."""
    if ncomp == 1:
        return t[6], t[7], t[8]
    dx0, dy0, dx1, dy1 = sx - t[1], sy - t[2], sx - t[10], sy - t[11]
    l0 = t[0] - 0.5 * ((dx0 * dx0 / t[3] + dy0 * dy0 / t[4]) + t[5])
    l1 = t[9] - 0.5 * ((dx1 * dx1 / t[12] + dy1 * dy1 / t[13]) + t[14])
    if l0 >= l1:
        h0, h1 = 1.0, math.exp(l1 - l0)
    else:
        h0, h1 = math.exp(l0 - l1), 1.0
    h = h0 + h1
    return (
        (h0 * t[6] + h1 * t[15]) / h,
        (h0 * t[7] + h1 * t[16]) / h,
        (h0 * t[8] + h1 * t[17]) / h,
    )


@njit(cache=True)
def cache_rehash(keys, vals, used, new_keys, new_vals, new_used, ist) -> None:
    """Move every entry of the fit cache into the larger arrays ``new_*``."""
    ist[1] = 0
    for i in range(len(used)):
        if used[i]:
            cache_put(keys[i], vals[i], used[i], new_keys, new_vals, new_used, ist)


# --------------------------------------------------------------------------- rollout


@njit(cache=True)
def _clip1(v: float) -> float:
    return -1.0 if v < -1.0 else (1.0 if v > 1.0 else v)


@njit(cache=True)
def rollout_kernel(gmr, geo, maha, fs, it, path, dists) -> None:
    """Algorithm 3 as autonomy.contextual's Python rollout computed it.

    ``gmr``: the LocalGMR arrays (:meth:`autonomy.local_gmr.LocalGMR.kernel_state`);
    ``geo``: ``lifted`` (p, 3) the target's surface points with their squared norms (p = 0:
    the fixed target ``fs[3:5]``); ``maha`` (7, 8) the Mahalanobis rows; ``fs``: floats
    (x, y, yaw, s0x, s0y, max speed, max yaw rate, dt, stop); ``it``: ints (steps cap,
    path rows, distances). Fills ``path`` (cap, 3) and ``dists`` (cap,).
    """
    k, inputs, features, origin, floor, tol, max_iter, cache_size = gmr[:8]
    meta, pidx, prel, lru, ist, keys, vals, used, counts = gmr[8:]
    lifted = geo
    x, y, yaw = fs[0], fs[1], fs[2]
    s0x, s0y, lim_v, lim_w, dt, stop = fs[3], fs[4], fs[5], fs[6], fs[7], fs[8]
    npts = lifted.shape[0]
    near = np.empty(k, dtype=np.int64)
    for _ in range(it[0]):
        if npts:  # Alg. 3, line 9: s* seen from the rolled-out pose
            h0, h1 = -2.0 * x, -2.0 * y
            best, ib = 0.0, 0
            for p in range(npts):
                d = dot3(lifted[p, 0], lifted[p, 1], lifted[p, 2], h0, h1, 1.0, npts)
                if p == 0 or d < best or (math.isnan(d) and not math.isnan(best)):
                    best, ib = d, p
            dx, dy = lifted[ib, 0] - x, lifted[ib, 1] - y
        else:
            dx, dy = s0x - x, s0y - y
        c, s = math.cos(yaw), math.sin(yaw)
        sx, sy = c * dx + s * dy, -s * dx + c * dy
        # line 10, Alg. 2: the k nearest demonstration points, their local fit, u*
        if not pool_search(sx, sy, k, meta, pidx, prel, lru, ist, near):
            fetch_pool(sx, sy, inputs, k, meta, pidx, prel, lru, ist, near)
        row = local_terms(
            near, features, origin, floor, tol, max_iter, cache_size, keys, vals, used, ist, counts
        )
        ux, uy, uw = predict_terms(vals[row], used[row], sx, sy)
        ux, uy, uw = _clip1(ux), _clip1(uy), _clip1(uw)
        speed = py_hypot(ux, uy)
        if speed >= 1e-6 and py_hypot(sx, sy) >= 1e-9:  # line 11: q_est, encoded
            theta = math.atan2(uy, ux) - math.atan2(sy, sx)
            ct, st = speed * math.cos(theta), speed * math.sin(theta)
        else:
            ct, st = speed, 0.0
        dist2 = 0.0
        for r in range(maha.shape[0]):
            a = maha[r]
            e = a[0] * sx + a[1] * sy + a[2] * ct + a[3] * st + a[4] * ux + a[5] * uy
            e = e + a[6] * uw + a[7]
            dist2 += e * e
        dist = math.sqrt(dist2)  # line 12, Eq. (6.3)
        dists[it[2]] = dist
        it[2] += 1
        if dist > stop:
            break
        vx, vy, w = ux * lim_v, uy * lim_v, uw * lim_w
        mid = yaw + 0.5 * w * dt  # line 14: holonomic kinematics, mid-step heading
        c, s = math.cos(mid), math.sin(mid)
        x += (c * vx - s * vy) * dt
        y += (s * vx + c * vy) * dt
        yaw += w * dt
        path[it[1], 0], path[it[1], 1], path[it[1], 2] = x, y, yaw
        it[1] += 1
