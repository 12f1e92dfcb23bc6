"""Compiled per-tick arithmetic of the kind-and-time recogniser (autonomy.kind_time): each
candidate's log-likelihood, marginalised over the primitives, with its best primitive, in
one loop (the numpy form costs some 0.15 ms a tick in call overheads)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

MIN_LOG_DISTANCE = math.log(0.05)  # autonomy.intent_prior.MIN_DISTANCE_M


@njit(cache=True)
def likelihood(
    mean, kind, dock, targets, normals, u, log_kind, exec_mean, exec_sd, prior, out, best
):
    """``out[c]`` = log L(c) and ``best[c]`` its best primitive (autonomy.kind_time).

    ``mean`` (n, J) SOGP means (non-finite taken as -1e3 or 1e3), ``kind`` (n,) int kind
    class, ``dock`` (n,) bool, ``targets`` and ``normals`` (n, 2), ``u`` (3,) normalised
    command, ``log_kind`` (J, 3), ``exec_mean`` and ``exec_sd`` (J,) [log m], ``prior``
    the floats (evidence_scale, distance_weight, approach mean, approach sd, rank_weight,
    axis_weight, toward_weight, dock_departure, exit_radius) then the log rank prior."""
    n, J = mean.shape
    a, wd, app_m, app_s = prior[0], prior[1], prior[2], prior[3]
    wr, w_axis, w_toward, departure = prior[4], prior[5], prior[6], prior[7]
    exit_radius = prior[8]
    ranks = prior.shape[0] - 9
    speed = math.sqrt(u[0] * u[0] + u[1] * u[1])
    for c in range(n):
        tx, ty = targets[c, 0], targets[c, 1]
        d = math.sqrt(tx * tx + ty * ty)
        x = math.log(d) if d > 0.05 else MIN_LOG_DISTANCE
        z = (x - app_m) / app_s
        log_app = -0.5 * z * z - math.log(app_s)
        top, jbest = -math.inf, 0
        lj = np.empty(J)
        for j in range(J):
            mu = mean[c, j]
            if not math.isfinite(mu):
                mu = -1e3 if (math.isnan(mu) or mu < 0) else 1e3
            ze = (x - exec_mean[j]) / exec_sd[j]
            log_exec = -0.5 * ze * ze - math.log(exec_sd[j])
            lj[j] = a * mu + log_kind[j, kind[c]] + wd * (log_exec - log_app)
            if lj[j] > top:
                top, jbest = lj[j], j
        total = 0.0
        for j in range(J):
            total += math.exp(lj[j] - top)
        value = top + math.log(total) + wr * prior[9 + min(c, ranks - 1)]
        if kind[c] == 0 and speed > 1e-9:
            ux, uy = u[0] / speed, u[1] / speed
            nx, ny = normals[c, 0], normals[c, 1]
            norm = math.sqrt(nx * nx + ny * ny)
            axis = abs(nx * ux + ny * uy) / norm if norm > 0 else 0.0
            toward = (tx * ux + ty * uy) / d if d > 1e-9 else 0.0
            if toward < 0.0 and not dock[c] and d <= exit_radius and norm > 0:
                # leaving through the passage: on its axis and moving along it
                toward = abs(nx * tx + ny * ty) / (norm * d) * axis
            value += w_axis * axis + w_toward * toward
            if dock[c] and toward < 0.0:
                value -= departure
        out[c] = value
        best[c] = jbest
