"""Compiled kernels of the contextual tick around the rollout (issue 25): the recogniser's
SOGP kernel matrix (Eq. 5.7), the candidates' task features (Sec. 5.1, 6.1) and the
tracking controller (autonomy.tracking). Like :mod:`autonomy._kernels`, each repeats the
numpy code it replaced operation by operation (tests/contextual_reference.py), so its
results are bit-identical; BLAS's products as chains of fused multiply-adds."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from autonomy._kernels import fma, py_hypot

# --------------------------------------------------------------------------- recognition


@njit(cache=True)
def sogp_kernels(Z, ls, xs_t, xs2, sf2, K) -> None:
    """The SOGP kernel values (Eq. 5.7) of the rows of ``Z`` (m, d) against every cluster's
    basis, as autonomy.sogp_recogniser.Recogniser computed them with numpy: ``K[j, b, i] =
    sf2[j] exp(-max(|xs[j, b]|^2 + |a|^2 - 2 xs[j, b].a, 0) / 2)``, ``a = Z[i] / ls[j]``;
    ``ls`` (c, d), ``xs_t`` (c, d, b) the basis / length scales transposed, ``xs2`` (c, b),
    ``sf2`` (c,), ``K`` (c, b, m) out. The products ``xs[j] @ a`` are BLAS's chains of
    fused multiply-adds over d, run for all b at once (independent chains vectorise)."""
    c, d, b = xs_t.shape
    m = Z.shape[0]
    a = np.empty(d)
    acc = np.empty(b)
    for j in range(c):
        for i in range(m):
            asum = 0.0
            for f in range(d):
                a[f] = Z[i, f] / ls[j, f]
                asum += a[f] * a[f]
            acc[:] = 0.0
            for f in range(d):
                af = a[f]
                for r in range(b):
                    acc[r] = fma(xs_t[j, f, r], af, acc[r])
            for r in range(b):
                sq = (xs2[j, r] + asum) - 2.0 * acc[r]
                if not (sq >= 0.0 or math.isnan(sq)):
                    sq = 0.0
                K[j, r, i] = math.exp(sq * -0.5) * sf2[j]


@njit(cache=True)
def gemv_rows(K, x, out) -> None:
    """numpy's ``x @ K`` for ``K`` (n, m) C-contiguous, m >= 2, ``x`` (n,): OpenBLAS's
    ``dgemv_n`` (Haswell) on the column-major (m, n) view. Rows below ``m - m % 4``: per
    four columns ``(K0 x0 + fma(K2, x2)) + (K1 x1 + fma(K3, x3))`` added to the row's
    sum, then two columns ``K0 x0 + K1 x1`` and one ``K0 x0``; the last ``m % 4`` rows
    a plain running sum over the columns (unrolled by four when ``m < 4``). The rows'
    sums run side by side (they vectorise)."""
    n, m = K.shape
    m3 = m & 3
    nb = m - m3
    out[:] = 0.0
    c = 0
    while c + 4 <= n:
        x0, x1, x2, x3 = x[c], x[c + 1], x[c + 2], x[c + 3]
        for r in range(nb):
            t4 = fma(K[c + 2, r], x2, K[c, r] * x0)
            t5 = fma(K[c + 3, r], x3, K[c + 1, r] * x1)
            out[r] = out[r] + (t4 + t5)
        c += 4
    if n & 2:
        for r in range(nb):
            out[r] = out[r] + (K[c, r] * x[c] + K[c + 1, r] * x[c + 1])
        c += 2
    if n & 1:
        for r in range(nb):
            out[r] = out[r] + K[c, r] * x[c]
    for r in range(nb, m):
        t = 0.0
        c = 0
        if nb == 0:  # the kernel's own loop for lda == m < 4
            while c + 4 <= n:
                t = t + (K[c, r] * x[c] + K[c + 1, r] * x[c + 1])
                t = t + (K[c + 2, r] * x[c + 2] + K[c + 3, r] * x[c + 3])
                c += 4
        while c < n:
            t = t + K[c, r] * x[c]
            c += 1
        out[r] = 0.0 + t


@njit(cache=True)
def gemv_dots(At, x, n, w, lanes) -> None:
    """numpy's ``A[:n, :n] @ x[:n]`` into ``w`` (n,), ``A`` C-contiguous, given as its
    transpose ``At``: OpenBLAS's ``dgemv_t`` (Haswell). The first ``nb = n - n % 4``
    terms of each dot product: four interleaved fused chains summed ``(l0 + l2) + (l1 +
    l3)`` (the outputs in fours); two plain chains of every other term, summed (a pair
    of outputs left over); four plain chains summed ``(l0 + l2) + (l1 + l3)`` (a single
    output left over). The last ``n % 4`` terms are added as the compiled C tail rounds
    them. The chains of all outputs run side by side in ``lanes`` (4, >= n) (they
    vectorise)."""
    nb = n - (n & 3)
    nq = 4 * (n >> 2)
    pair = nq + 2 if n & 2 else nq  # outputs [nq, pair): two chains; [pair, n): four
    l0, l1, l2, l3 = lanes[0], lanes[1], lanes[2], lanes[3]
    l0[:n] = 0.0
    l1[:n] = 0.0
    l2[:n] = 0.0
    l3[:n] = 0.0
    for r in range(0, nb, 4):
        x0, x1, x2, x3 = x[r], x[r + 1], x[r + 2], x[r + 3]
        for c in range(nq):
            l0[c] = fma(At[r, c], x0, l0[c])
            l1[c] = fma(At[r + 1, c], x1, l1[c])
            l2[c] = fma(At[r + 2, c], x2, l2[c])
            l3[c] = fma(At[r + 3, c], x3, l3[c])
        for c in range(nq, pair):
            l0[c] = (l0[c] + At[r, c] * x0) + At[r + 2, c] * x2
            l1[c] = (l1[c] + At[r + 1, c] * x1) + At[r + 3, c] * x3
        for c in range(pair, n):
            l0[c] = l0[c] + At[r, c] * x0
            l1[c] = l1[c] + At[r + 1, c] * x1
            l2[c] = l2[c] + At[r + 2, c] * x2
            l3[c] = l3[c] + At[r + 3, c] * x3
    for c in range(n):
        if nb == 0:  # no kernel ran: the outputs stay BLAS's zeros
            w[c] = 0.0
        elif nq <= c < pair:
            w[c] = 0.0 + (l0[c] + l1[c])
        else:
            w[c] = 0.0 + ((l0[c] + l2[c]) + (l1[c] + l3[c]))
    r = nb
    for c in range(n):
        if n & 3 == 3:
            w[c] = w[c] + fma(At[r + 2, c], x[r + 2], fma(At[r, c], x[r], At[r + 1, c] * x[r + 1]))
        elif n & 3 == 2:
            w[c] = w[c] + fma(At[r, c], x[r], At[r + 1, c] * x[r + 1])
        elif n & 3 == 1:
            w[c] = fma(At[r, c], x[r], w[c])


@njit(cache=True)
def dot_strided(x, y, n) -> float:
    """numpy's ``x[:n] @ y[:n]`` when ``x`` is a non-contiguous view (OpenBLAS ``ddot``
    with a stride): products in fours, ``t1 += p0 + p2``, ``t2 += p1 + p3``, the rest
    added to ``t1``; ``t1 + t2``."""
    t1, t2 = 0.0, 0.0
    i = 0
    while i + 4 <= n:
        t1 = t1 + (y[i] * x[i] + y[i + 2] * x[i + 2])
        t2 = t2 + (y[i + 1] * x[i + 1] + y[i + 3] * x[i + 3])
        i += 4
    while i < n:
        t1 = t1 + y[i] * x[i]
        i += 1
    return 0.0 + (t1 + t2)


@njit(cache=True)
def argmax_finite(scores) -> tuple[int, int]:
    """autonomy.sogp_classifier.argmax_finite of a (m, c) float64 array: the row and
    column of the first largest finite entry in row-major order; (-1, -1) if none."""
    m, c = scores.shape
    bi, bj, best = -1, -1, 0.0
    for i in range(m):
        for j in range(c):
            v = scores[i, j]
            if math.isfinite(v) and (bi < 0 or v > best):
                bi, bj, best = i, j, v
    return bi, bj


@njit(cache=True)
def recognise(K, alpha, n_basis, Ct, sf2, noise, mean, work) -> tuple[int, int, float]:
    """Eqs. (5.6), (5.8) and (5.9) of autonomy.sogp_recogniser.Recogniser for m >= 2
    candidates, as numpy computed them: the posterior means ``mean[j] = alpha[j] @ K[j]``
    (``K`` (c, b, m), ``alpha`` (c, b), ``mean`` (c, m) out, :func:`gemv_rows`), the
    winner (:func:`argmax_finite` of ``mean.T``) and its predictive variance
    ``max(sf2 + k @ (C_j @ k), 0) + noise`` (``k = K[j, :n_j, i]``, ``Ct`` (c, b, b)
    the ``C_j`` transposed, zero-padded; :func:`gemv_dots`, :func:`dot_strided`;
    ``work`` (6, b)). Returns
    (candidate, cluster row, variance); (-1, -1, 0) when no mean is finite."""
    for j in range(K.shape[0]):
        gemv_rows(K[j], alpha[j], mean[j])
    bi, bj = argmax_finite(mean.T)
    if bi < 0:
        return -1, -1, 0.0
    n = n_basis[bj]
    k, w = work[0], work[1]
    for r in range(n):
        k[r] = K[bj, r, bi]
    gemv_dots(Ct[bj], k, n, w, work[2:])
    var = sf2[bj] + dot_strided(k, w, n)
    if 0.0 > var:
        var = 0.0
    return bi, bj, var + noise[bj]


@njit(cache=True)
def lift_points(points):
    """``np.column_stack((points, np.einsum("ij,ij->i", points, points)))`` of surface
    points (p, 2) [m]: (p, 3), the squared norms ``x * x + y * y`` as einsum sums two
    columns."""
    p = points.shape[0]
    out = np.empty((p, 3))
    for i in range(p):
        x, y = points[i, 0], points[i, 1]
        out[i, 0], out[i, 1], out[i, 2] = x, y, x * x + y * y
    return out


@njit(cache=True)
def _before(a: float, b: float) -> bool:
    """``a`` sorts before ``b`` in numpy's order (NaN last)."""
    return a < b or (math.isnan(b) and not math.isnan(a))


@njit(cache=True)
def _wrap(a: float) -> float:
    """autonomy.features.wrap_angle of one angle [rad]."""
    w = math.atan2(math.sin(a), math.cos(a))
    return math.pi if w <= -math.pi else w


@njit(cache=True)
def candidate_features(targets, n, u, mean, scale, Z, chosen) -> int:
    """Steps 1-2 of the contextual tick as numpy computed them: the ``n`` candidates whose
    target points ``targets`` (p, 2) [m] are nearest the robot (stable order, as
    autonomy.contextual._nearest_candidates) into ``chosen``, and their standardised
    encoded task features (autonomy.features.task_features, encode; the scaler's
    ``mean``, ``scale`` (7,)) into the rows of ``Z`` (n, 7), for the normalised command
    ``u`` (3,). Returns the number of candidates."""
    p = targets.shape[0]
    m = min(n, p)
    bd = np.empty(m)
    for t in range(p):
        d = targets[t, 0] * targets[t, 0] + targets[t, 1] * targets[t, 1]
        if t < m:
            pos = t
        elif _before(d, bd[m - 1]):
            pos = m - 1
        else:
            continue
        while pos > 0 and _before(d, bd[pos - 1]):
            bd[pos], chosen[pos] = bd[pos - 1], chosen[pos - 1]
            pos -= 1
        bd[pos], chosen[pos] = d, t
    speed = math.hypot(u[0], u[1])
    heading = math.atan2(u[1], u[0])
    for r in range(m):
        sx, sy = targets[chosen[r], 0], targets[chosen[r], 1]
        theta = _wrap(heading - math.atan2(sy, sx))  # Sec. 6.1
        if not (math.hypot(sx, sy) >= 1e-9 and speed >= 1e-6):
            theta = 0.0
        q = (sx, sy, speed * math.cos(theta), speed * math.sin(theta), u[0], u[1], u[2])
        for f in range(7):
            Z[r, f] = (q[f] - mean[f]) / scale[f]
    return m


@njit(cache=True)
def track_kernel(path, dt, max_speed, max_yaw_rate, lookahead, min_time, out) -> None:
    """autonomy.tracking.track as numpy computed it, for a path (k, 3), k >= 1: the
    command (3,) into ``out`` (np.unwrap, np.hypot and np.clip written out)."""
    k = path.shape[0]
    yaw = np.empty(k + 1)  # (0, np.unwrap(path[:, 2]))
    arc = np.empty(k + 1)  # (0, cumsum of the segment lengths)
    yaw[0], arc[0] = 0.0, 0.0
    if k:
        yaw[1] = path[0, 2]
    period = 2.0 * math.pi
    correct = 0.0
    for t in range(k - 1):
        dd = path[t + 1, 2] - path[t, 2]
        mod = np.fmod(dd + math.pi, period)  # numpy's float mod: sign of the divisor
        if mod != 0.0:
            if mod < 0.0:
                mod += period
        else:
            mod = 0.0
        ddmod = mod + -math.pi
        if ddmod == -math.pi and dd > 0:
            ddmod = math.pi
        ph = ddmod - dd
        if abs(dd) < math.pi:
            ph = 0.0
        correct = ph if t == 0 else correct + ph
        yaw[t + 2] = path[t + 1, 2] + correct
    px, py = 0.0, 0.0
    for t in range(k):
        h = math.hypot(path[t, 0] - px, path[t, 1] - py)
        arc[t + 1] = h if t == 0 else arc[t] + h
        px, py = path[t, 0], path[t, 1]
    total = arc[k]
    if total < 1e-9:  # a predicted pure rotation
        t_end = k * dt
        if min_time > t_end:
            t_end = min_time
        out[0], out[1], out[2] = 0.0, 0.0, _clip(_wrap(yaw[k]) / t_end, max_yaw_rate)
        return
    target = total if total < lookahead else lookahead
    idx = 0
    while idx <= k and not (arc[idx] > target):
        idx += 1
    i = min(idx - 1, k - 1)
    span = arc[i + 1] - arc[i]
    f = (target - arc[i]) / span if span > 0 else 1.0
    x0 = path[i - 1, 0] if i else 0.0
    y0 = path[i - 1, 1] if i else 0.0
    qx, qy = x0 + f * (path[i, 0] - x0), y0 + f * (path[i, 1] - y0)
    yaw_l = yaw[i] + f * (yaw[i + 1] - yaw[i])
    t_l = (i + f) * dt
    if min_time > t_l:
        t_l = min_time
    speed = target / t_l
    dist = py_hypot(qx, qy)
    if dist > 1e-12:
        qx, qy = qx / dist, qy / dist
    else:
        qx, qy = 0.0, 0.0
    if max_speed < speed:
        speed = max_speed
    out[0], out[1], out[2] = speed * qx, speed * qy, _clip(yaw_l / t_l, max_yaw_rate)


@njit(cache=True)
def _clip(v: float, limit: float) -> float:
    """np.clip(v, -limit, limit) (NaN stays NaN)."""
    if math.isnan(v):
        return v
    v = v if v > -limit else -limit
    return v if v < limit else limit
