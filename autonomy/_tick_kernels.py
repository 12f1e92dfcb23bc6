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
    basis, as autonomy.contextual.Recogniser computed them with numpy: ``K[j, b, i] =
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
