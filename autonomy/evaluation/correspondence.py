"""Correspondence and tightness of recognition (thesis Sec. 7.4.1, Tables 7.7-7.9): the
correspondence rate (CR) of the most probable semantic component per test trajectory,
its average over trajectories (ACR), and the intra-cluster average dissimilarity (ICAD)
of the winning query feature to the training points of the assigned cluster, with its
mean over way points (MICAD)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.distance import cdist

_CHUNK = 512  # query rows per distance block: (512, n_c) floats at a time


def correspondence_rates(hit: np.ndarray, run: np.ndarray) -> dict[str, float]:
    """Correspondence rate (CR, Sec. 7.4.1) of every test trajectory: the share of its
    way points at which the most probable semantic component is the ground-truth target.

    Parameters
    ----------
    hit : numpy.ndarray
        (n,) bool, per way point: the winning component (Eq. 5.8) is the target.
    run : numpy.ndarray
        (n,) the trajectory (run) of every way point.

    Returns
    -------
    dict
        ``str(run)`` -> CR in [0, 1], runs in sorted order. The ACR is the mean of the
        values (every trajectory weighs the same, however long).
    """
    hit = np.asarray(hit, dtype=bool)
    run = np.asarray(run)
    if hit.shape != run.shape:
        raise ValueError(f"correspondence_rates: hit {hit.shape} and run {run.shape} differ")
    return {str(r): float(np.mean(hit[run == r])) for r in np.unique(run)}


def intra_cluster_dissimilarity(
    Q: np.ndarray, Z_train: np.ndarray, y_train: np.ndarray, assigned: np.ndarray
) -> np.ndarray:
    """Intra-cluster average dissimilarity (ICAD, Sec. 7.4.1) of query features: the
    mean L2 distance of each query to all training points of the cluster it is
    assigned to (its "tightness" to that cluster).

    Parameters
    ----------
    Q : numpy.ndarray
        (n, d) winning query features, in the (standardised) space of ``Z_train``.
    Z_train : numpy.ndarray
        (t, d) training points.
    y_train : numpy.ndarray
        (t,) their cluster labels.
    assigned : numpy.ndarray
        (n,) the cluster assigned to every query; each must label some training point.

    Returns
    -------
    numpy.ndarray
        (n,) ICAD >= 0, in the units of ``Q``; MICAD is their mean.
    """
    Q = np.atleast_2d(np.asarray(Q, dtype=float))
    Z_train = np.asarray(Z_train, dtype=float)
    y_train, assigned = np.asarray(y_train), np.asarray(assigned)
    if len(assigned) != len(Q):
        raise ValueError(f"intra_cluster_dissimilarity: {len(Q)} queries, {len(assigned)} labels")
    out = np.empty(len(Q))
    for c in np.unique(assigned):
        members = Z_train[y_train == c]
        if len(members) == 0:
            raise ValueError(f"intra_cluster_dissimilarity: cluster {c!r} has no training point")
        rows = np.flatnonzero(assigned == c)
        for a in range(0, len(rows), _CHUNK):
            block = rows[a : a + _CHUNK]
            out[block] = cdist(Q[block], members).mean(axis=1)  # L2 dissimilarity
    return out
