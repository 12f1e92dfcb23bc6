"""Floating-point comparisons that hold on every x86-64 CPU (issue 36).

The compiled kernels (autonomy._kernels, autonomy._tick_kernels) repeat numpy's code
operation by operation, and its BLAS products as the chains of fused multiply-adds of
OpenBLAS's Haswell kernels; on a CPU whose OpenBLAS picks another kernel (SkylakeX and Zen
with AVX-512, Sandybridge and older without FMA) the BLAS side sums in another order, so a
kernel and its numpy reference agree only to rounding. The tolerances here are the bounds
of that rounding, each with its reason:

- a sum of ``n`` products: both orders lie within ``gamma_n * sum |a_i b_i|`` of the exact
  sum (Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., Eq. 3.5), so
  they differ by at most twice that: :func:`dot_tolerance`;
- a quantity made by a chain of such sums (an EM fit to convergence, a GMR prediction, a
  rollout, a tracking command, a recogniser's blend weight): :data:`PIPELINE_RTOL`
  relative to its magnitude (see there);
- a discrete decision taken on such a quantity (an argmax, an iteration count, a chosen
  candidate) must agree unless the reference's deciding margin is within the tolerance
  of the quantity it is taken on: a near-tie, where either answer is right.

Non-finite values must match exactly (NaN where NaN, the same infinities).

With ``ASA_FP_LOG=FILE`` every comparison appends ``name largest-ratio`` (the largest
difference found over its tolerance) to FILE, which is how the figures of the closing
note of issue 36 were measured on several OpenBLAS kernels (``OPENBLAS_CORETYPE``).
"""

from __future__ import annotations

import os

import numpy as np

U = 2.0**-53  # unit roundoff of float64

# A chain of BLAS sums inside an iteration (EM to convergence, 100 iterations at most; a
# rollout of up to 60 GMR steps, each an EM fit) moves a result by a few ulps per step,
# amplified by the conditioning of what is fitted (variance floors 1e-3 against data of
# order 1: a condition number up to about 1e4): 60 steps x 1e4 x 1e-16 ~ 1e-10. Measured
# across OpenBLAS's Haswell, Sandybridge and Nehalem kernels the largest is below 1e-11
# (docs/results.md, issue 36); 1e-9 keeps that headroom and still fails any change of a
# formula, which moves results by far more than 1e-6.
PIPELINE_RTOL = 1e-9


def gamma(n: int | np.ndarray) -> float | np.ndarray:
    """``gamma_n = n u / (1 - n u)``, the bound of a sum of ``n`` rounded products."""
    n = np.asarray(n, dtype=float)
    return n * U / (1.0 - n * U)


def dot_tolerance(abs_a: np.ndarray, abs_b: np.ndarray) -> np.ndarray:
    """Largest difference between two summation orders of ``a @ b``: ``2 gamma_n |a| @ |b|``
    (``n`` the inner dimension), plus one ulp of the smallest normal for underflow."""
    n = np.shape(abs_a)[-1]
    with np.errstate(invalid="ignore", over="ignore"):
        return 2.0 * gamma(n + 1) * (abs_a @ abs_b) + np.finfo(float).tiny


def _log(name: str, ratio: float) -> None:
    path = os.environ.get("ASA_FP_LOG")
    if path:
        with open(path, "a", encoding="utf-8") as f:
            f.write(f"{name} {ratio:.3g}\n")


def assert_close(got, ref, tol, *, name: str = "value") -> None:
    """``|got - ref| <= tol`` elementwise where ``ref`` is finite; non-finite entries of
    ``ref`` must be matched exactly (NaN by NaN, an infinity by the same infinity)."""
    got, ref = np.asarray(got, dtype=float), np.asarray(ref, dtype=float)
    tol = np.broadcast_to(np.asarray(tol, dtype=float), ref.shape)
    assert got.shape == ref.shape, f"{name}: shape {got.shape} != {ref.shape}"
    finite = np.isfinite(ref)
    assert np.array_equal(got[~finite], ref[~finite], equal_nan=True), (
        f"{name}: non-finite entries differ"
    )
    # a tolerance that is itself not finite (a product of huge values) checks only that
    # the kernel's value is finite where the reference's is
    bounded = finite & np.isfinite(tol)
    assert np.all(np.isfinite(got[finite])), f"{name}: non-finite where the reference is finite"
    diff = np.abs(got[bounded] - ref[bounded])
    ratio = float(np.max(diff / np.maximum(tol[bounded], 1e-300), initial=0.0))
    _log(name, ratio)
    assert ratio <= 1.0, (
        f"{name}: differs by {float(np.max(diff)):.3g}, beyond its tolerance "
        f"(largest difference / tolerance {ratio:.3g})"
    )


def assert_pipeline_close(got, ref, *, name: str = "value", scale=None) -> None:
    """:func:`assert_close` with :data:`PIPELINE_RTOL` relative to ``scale`` (default the
    largest finite magnitude of ``ref``, at least 1)."""
    ref_a = np.asarray(ref, dtype=float)
    if scale is None:
        finite = np.abs(ref_a[np.isfinite(ref_a)])
        scale = max(float(np.max(finite, initial=0.0)), 1.0)
    assert_close(got, ref, PIPELINE_RTOL * np.asarray(scale), name=name)


def near_best(values, tol) -> np.ndarray:
    """Mask of the finite ``values`` within the tolerance of the largest: those an argmax
    may pick on another CPU (``tol`` broadcast like ``values``; two entries are tied when
    their difference is within the sum of their tolerances)."""
    v = np.asarray(values, dtype=float)
    tol = np.broadcast_to(np.asarray(tol, dtype=float), v.shape)
    finite = np.isfinite(v)
    if not finite.any():
        return finite
    best = np.unravel_index(np.argmax(np.where(finite, v, -np.inf)), v.shape)
    return finite & (v[best] - v <= tol[best] + tol)
