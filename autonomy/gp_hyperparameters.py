"""Hyperparameters of a GP regression by type-II maximum likelihood: the full GP's log
evidence (thesis Sec. 5.2, Eq. 5.11; Rasmussen & Williams Sec. 5.4) maximised with
L-BFGS-B under a length-scale cap. Choices where the thesis is silent:
docs/decisions.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_solve, lapack
from scipy.optimize import minimize

from autonomy.gp_kernel import se_ard_kernel
from autonomy.sogp import MAX_LENGTH_SCALE


def log_evidence(log_params: np.ndarray, X: np.ndarray, y: np.ndarray) -> tuple[float, np.ndarray]:
    """Log evidence of the full GP and its gradient (Eq. 5.11; Rasmussen & Williams 5.9).

    ``log p(y | X) = -y^T A^-1 y / 2 - log|A| / 2 - n log(2 pi) / 2``, ``A = K + noise I``;
    ``d/dtheta = tr((a a^T - A^-1) dA/dtheta) / 2`` with ``a = A^-1 y``.

    Parameters
    ----------
    log_params : numpy.ndarray
        (d + 2,) ``(log l_1, ..., log l_d, log signal_var, log noise_var)``.
    X : numpy.ndarray
        (n, d) inputs.
    y : numpy.ndarray
        (n,) targets.

    Returns
    -------
    value : float
        The log evidence (``-inf`` if ``A`` is not positive definite).
    grad : numpy.ndarray
        (d + 2,) its gradient with respect to ``log_params``.
    """
    X = np.asarray(X, dtype=float)
    y = np.asarray(y, dtype=float)
    n, d = X.shape
    theta = np.asarray(log_params, dtype=float)
    ls = np.exp(theta[:d])
    sf2 = float(np.exp(theta[d]))
    sn2 = float(np.exp(theta[d + 1]))
    K = se_ard_kernel(X, X, length_scales=ls, signal_var=sf2)
    A = K + sn2 * np.eye(n)
    L, info = lapack.dpotrf(A, lower=1, clean=1)
    if info != 0:
        return -np.inf, np.zeros(d + 2)
    a = cho_solve((L, True), y, check_finite=False)
    logdet = 2.0 * np.log(np.diag(L)).sum()
    value = -0.5 * float(y @ a) - 0.5 * logdet - 0.5 * n * np.log(2.0 * np.pi)  # Eq. (5.11)
    Ainv, info = lapack.dpotri(L, lower=1)  # lower triangle of A^-1, from the factor
    if info != 0:
        return -np.inf, np.zeros(d + 2)
    Ainv = np.tril(Ainv) + np.tril(Ainv, -1).T
    W = np.outer(a, a) - Ainv
    M = W * K
    grad = np.empty(d + 2)
    # dK/dlog l_j = K * (x_ij - x_kj)^2 / l_j^2; sum_ik M_ik (x_ij - x_kj)^2 expanded.
    Xs = X / ls
    rows = M.sum(axis=1)
    grad[:d] = 0.5 * (2.0 * (rows @ (Xs * Xs)) - 2.0 * np.einsum("ij,ij->j", Xs, M @ Xs))
    grad[d] = 0.5 * float(np.sum(M))  # dK/dlog sf2 = K
    grad[d + 1] = 0.5 * sn2 * float(np.trace(W))  # dA/dlog sn2 = sn2 I
    return value, grad


def initial_log_params(X: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Heuristic start for :func:`fit_hyperparameters`, (d + 2,) log parameters."""
    X = np.asarray(X, dtype=float)
    std = _column_scale(X)
    v = _target_scale(y)
    return np.concatenate([np.log(std * np.sqrt(X.shape[1])), [np.log(v), np.log(0.1 * v)]])


def hyperparameter_bounds(
    X: np.ndarray, y: np.ndarray, *, max_length_scale: float = MAX_LENGTH_SCALE
) -> list[tuple[float, float]]:
    """Bounds on the log parameters used by :func:`fit_hyperparameters`.

    Parameters
    ----------
    X : numpy.ndarray
        (n, d) inputs.
    y : numpy.ndarray
        (n,) targets.
    max_length_scale : float
        Upper bound of every length scale, in standard deviations of its column (> 0.01).

    Returns
    -------
    list of (float, float)
        (d + 2,) ``(low, high)`` bounds of the log length scales, log signal variance and
        log noise variance.
    """
    if not (np.isfinite(max_length_scale) and max_length_scale > 1e-2):
        raise ValueError(f"max_length_scale: must be a number > 0.01, got {max_length_scale!r}")
    std = _column_scale(np.asarray(X, dtype=float))
    v = _target_scale(y)
    bounds = [(float(np.log(1e-2 * s)), float(np.log(max_length_scale * s))) for s in std]
    bounds.append((float(np.log(1e-2 * v)), float(np.log(1e1 * v))))
    bounds.append((float(np.log(1e-2 * v)), float(np.log(1e1 * v))))
    return bounds


def _column_scale(X: np.ndarray) -> np.ndarray:
    std = X.std(axis=0)
    return np.where(std > 1e-12, std, 1.0)


def _target_scale(y: np.ndarray) -> float:
    v = float(np.mean(np.asarray(y, dtype=float) ** 2))
    return v if v > 1e-12 else 1.0


@dataclass(frozen=True, slots=True)
class Hyperparameters:
    """The result of :func:`fit_hyperparameters`.

    ``binding`` names the parameters (``"length_scale_<j>"``, ``"signal_var"``,
    ``"noise_var"``) that sit at a bound the evidence pushes against: its gradient there
    points out of the box by more than ``BINDING_GRADIENT`` nats per log unit. A length
    scale at its upper bound with a flat evidence has switched its dimension off (ARD)
    and is not binding; ``switched_off`` lists those dimensions.
    """

    length_scales: np.ndarray  # (d,)
    signal_var: float
    noise_var: float
    log_evidence: float  # Eq. (5.11) at the optimum, on the subsample [nats]
    binding: tuple[str, ...]
    switched_off: tuple[int, ...]


BINDING_GRADIENT = 1e-2  # [nats per log unit] below it the evidence is flat at a bound


def binding_bounds(
    theta: np.ndarray, grad: np.ndarray, bounds: list[tuple[float, float]]
) -> tuple[tuple[str, ...], tuple[int, ...]]:
    """Which log parameters ``theta`` (d + 2,) sit at a bound of ``bounds`` that the
    log-evidence gradient ``grad`` (d + 2,) pushes against, and which length scales sit
    at their upper bound with a flat evidence (switched-off dimensions)."""
    d = len(theta) - 2
    names = [f"length_scale_{j}" for j in range(d)] + ["signal_var", "noise_var"]
    binding, off = [], []
    for k, ((lo, hi), t, g) in enumerate(zip(bounds, theta, grad, strict=True)):
        at_lo, at_hi = t <= lo + 1e-6, t >= hi - 1e-6
        if (at_lo and g < -BINDING_GRADIENT) or (at_hi and g > BINDING_GRADIENT):
            binding.append(names[k])
        elif at_hi and k < d:
            off.append(k)
    return tuple(binding), tuple(off)


def fit_hyperparameters(
    X: np.ndarray,
    y: np.ndarray,
    *,
    rng: np.random.Generator,
    max_points: int = 600,
    restarts: int = 3,
    max_length_scale: float = MAX_LENGTH_SCALE,
) -> Hyperparameters:
    """Type-II maximum likelihood hyperparameters of the full GP (Sec. 5.2, Eq. 5.11).

    Parameters
    ----------
    X : numpy.ndarray
        (n, d) inputs.
    y : numpy.ndarray
        (n,) targets.
    rng : numpy.random.Generator
        Draws the subsample (when n > max_points) and the random restarts.
    max_points : int
        At most this many points (drawn uniformly without replacement) enter the evidence.
    restarts : int
        Number of L-BFGS-B runs (>= 1): the heuristic start, then random ones.
    max_length_scale : float
        Upper bound of the length scales in standard deviations of their columns (short
        for the recogniser: docs/decisions.md).

    Returns
    -------
    Hyperparameters
        The SE-ARD length scales (d,), signal and noise variance, the evidence and which
        bounds bind (:func:`binding_bounds`).
    """
    X = np.asarray(X, dtype=float)
    y = np.asarray(y, dtype=float).reshape(-1)
    if X.ndim != 2 or X.shape[0] != y.shape[0] or X.shape[0] < 2:
        raise ValueError(f"X, y: need (n, d) and (n,) with n >= 2, got {X.shape}, {y.shape}")
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(y))):
        raise ValueError("X, y: must be finite (no NaN or inf)")
    if X.shape[0] > max_points:
        idx = rng.choice(X.shape[0], size=max_points, replace=False)
        X, y = X[idx], y[idx]
    d = X.shape[1]
    bounds = hyperparameter_bounds(X, y, max_length_scale=max_length_scale)
    lo = np.array([b[0] for b in bounds])
    hi = np.array([b[1] for b in bounds])
    start = np.clip(initial_log_params(X, y), lo, hi)

    def negative(theta: np.ndarray) -> tuple[float, np.ndarray]:
        value, grad = log_evidence(theta, X, y)
        if not np.isfinite(value):
            return 1e25, np.zeros_like(theta)
        return -value, -grad

    best_theta, best_value = start, negative(start)[0]
    for attempt in range(max(1, int(restarts))):
        theta0 = start if attempt == 0 else np.clip(start + rng.normal(0.0, 1.0, d + 2), lo, hi)
        res = minimize(negative, theta0, jac=True, method="L-BFGS-B", bounds=bounds)
        if res.fun < best_value:
            best_theta, best_value = res.x, float(res.fun)
    value, grad = log_evidence(best_theta, X, y)
    binding, off = binding_bounds(best_theta, grad, bounds)
    return Hyperparameters(
        length_scales=np.exp(best_theta[:d]),
        signal_var=float(np.exp(best_theta[d])),
        noise_var=float(np.exp(best_theta[d + 1])),
        log_evidence=float(value),
        binding=binding,
        switched_off=off,
    )
