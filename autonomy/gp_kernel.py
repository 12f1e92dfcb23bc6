"""The squared-exponential ARD kernel of the GPs (thesis Sec. 5.2, Eq. 5.7) and a
jittered Cholesky factorisation of a kernel matrix."""

from __future__ import annotations

import numpy as np
from scipy.linalg import cho_factor


def se_ard_kernel(
    A: np.ndarray, B: np.ndarray, *, length_scales: np.ndarray, signal_var: float
) -> np.ndarray:
    """Squared-exponential kernel with one length scale per input dimension (Eq. 5.7).

    ``k(a, b) = signal_var * exp(-0.5 * sum_j ((a_j - b_j) / l_j)^2)``

    Parameters
    ----------
    A : numpy.ndarray
        (n, d) inputs.
    B : numpy.ndarray
        (m, d) inputs.
    length_scales : numpy.ndarray
        (d,) length scales, in the inputs' units.
    signal_var : float
        Signal variance, in the squared output unit.

    Returns
    -------
    numpy.ndarray
        (n, m) kernel matrix.
    """
    ls = np.asarray(length_scales, dtype=float)
    a = np.asarray(A, dtype=float) / ls
    b = np.asarray(B, dtype=float) / ls
    sq = (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * (a @ b.T)
    return signal_var * np.exp(-0.5 * np.maximum(sq, 0.0))  # Eq. (5.7), ARD


def cholesky_with_jitter(A: np.ndarray, jitter: float) -> tuple[np.ndarray, bool] | None:
    """``cho_factor`` of ``A + jitter I``, the jitter raised tenfold (12 times at most)
    until it factors; None if it never does."""
    eye = np.eye(A.shape[0])
    for _ in range(12):
        try:
            return cho_factor(A + jitter * eye, lower=False, check_finite=False)
        except np.linalg.LinAlgError:
            jitter *= 10.0
    return None
