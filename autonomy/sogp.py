"""Sparse Online Gaussian Process regression (Csató & Opper 2002; thesis Sec. 5.2, 7.3).

The posterior of a zero-mean GP with squared-exponential ARD kernel and Gaussian noise
(thesis eqs. 5.4-5.7, 5.9) is kept in Csató & Opper's parametrisation over a set of at
most ``capacity`` basis vectors (BVs)::

    mean(x)  = k_x^T alpha                            # Eq. (5.6)
    var(x)   = k(x, x) + k_x^T C k_x + noise_var      # Eq. (5.9)

with ``k_x`` the kernel between the BVs and ``x`` and ``Q`` the inverse Gram matrix of
the BVs. One observation ``(x, y)`` is absorbed exactly (Gaussian likelihood) by the
rank-one updates of Csató & Opper (2002), "Sparse on-line Gaussian processes", Neural
Computation 14(3), Sec. 3-4 ("C&O" below):

- ``q = (y - m_x) / (s2_x + noise_var)``, ``r = -1 / (s2_x + noise_var)`` with the current
  predictive mean ``m_x`` and latent variance ``s2_x`` at ``x``;
- projection ``e_hat = Q k_x`` and novelty ``gamma = k(x, x) - k_x^T e_hat``;
- ``gamma < novelty_tol * k(x, x)``: reduced update without a new BV,
  ``s = C k_x + e_hat`` (the tolerance is relative to the signal variance ``k(x, x)``, so it
  does not depend on the targets' units);
- otherwise the full update: ``s = (C k_x, 1)``, alpha, C and Q grow by one;
- ``alpha += q s``, ``C += r s s^T``, ``Q += (e_hat, -1)(e_hat, -1)^T / gamma``;
- above capacity, the BV with the smallest score ``alpha_i^2 / (Q_ii + C_ii)`` is deleted
  with C&O's deletion equations (see :meth:`SparseOnlineGP._delete`).

With capacity above the number of observations and every point novel, the result is the
full GP posterior exactly (tested to 1e-6).

Decisions where the thesis and the brief are silent:

- The reduced update treats the *projected* observation exactly: the projected latent has
  variance ``s2_x - gamma``, so ``q`` and ``r`` are scaled by ``eta = 1 / (1 + r gamma)``
  (Csató's own reference implementation does the same; as ``gamma -> 0`` it is C&O's
  update).
- Numerics: ``C`` and ``Q`` are stored as the upper triangle of preallocated
  Fortran-ordered arrays (grown by doubling up to ``capacity + 1``) and changed with BLAS
  ``dsyr``/``dsyr2``/``dsymv`` in place, so an update at capacity 500 costs a few
  O(b^2) level-2 calls and no inversion. A deleted BV's slot is refilled by the last BV,
  keeping the storage compact. Every ``recondition_every`` updates ``Q`` is recomputed
  from the BVs' Gram matrix by Cholesky with a jitter of ``1e-10 * signal_var`` (raised
  tenfold until it factors) to stop rounding drift; ``alpha`` and ``C`` are left as they
  are (they carry the data). The latent variance is clamped at 0, so the predictive
  variance is never below ``noise_var``. Deletion scores use ``max(Q_ii + C_ii, tiny)``.
- At capacity, the scores after a prospective addition are computed first, in O(b). When
  the new point itself would be the one deleted, adding and deleting it is replaced by the
  reduced update with ``eta = 1``, which C&O's equations make identical (the test checks
  it against the verbatim equations); this skips two thirds of the O(b^2) work on most
  updates once the basis is full.
- Batch prediction caches the dense symmetric ``C`` and the BVs' norms until the next
  update (one GEMM instead of BLAS ``symm``, which is slow on thin query blocks);
  :meth:`SparseOnlineGP.predict_mean` skips the variance, all the score (5.8) needs.
- All level-2 BLAS work here is memory-bound: a multi-threaded BLAS only slows it down,
  badly so on a busy 2-core machine (measured 5-8x). Callers that run many updates
  (training, the benchmark) should limit BLAS to one thread (``threadpoolctl``); this
  module does not, as ``autonomy`` imports only numpy, scipy and scikit-learn.
- :meth:`SparseOnlineGP.fit` resets the model and feeds the rows in the given order
  (shuffling is the caller's choice, see the classifier).
- :meth:`SparseOnlineGP.refine` (a decision beyond the thesis, used by the offline
  evaluation) replaces the single pass's posterior by the one repeated passes converge
  to on the chosen basis, in closed form (the projected process). On the demonstrations
  it raised the classifier's F0.5 at capacity 600 by up to .05 (doorway crossing), for
  a fraction of the online pass's cost (see ``autonomy.evaluation``).
- :func:`fit_hyperparameters` maximises the full GP's log evidence (5.11) with L-BFGS-B on
  ``log`` parameters from a heuristic start (length scale ``sqrt(d) * std`` per input
  column, signal variance ``mean(y^2)``, noise ``0.1 mean(y^2)``) and ``restarts - 1``
  random starts (log-normal jitter of scale 1 around it). Bounds: length scale in
  ``[1e-2, max_length_scale] * std`` of its column (std 0 counts as 1;
  ``max_length_scale`` = :data:`MAX_LENGTH_SCALE` = 0.5 by default), signal and noise
  variance in ``[1e-2, 10] * v`` with ``v = mean(y^2)`` (1 if zero), so the
  signal-to-noise ratio is at most 1e3.
- Why the length scales are capped at half a standard deviation. The evidence of a
  one-vs-all GP on the demonstrated targets' features keeps rising with the length scale
  in most input columns (the classes are separable along a few of them), so with the old
  cap of 100 std most GPs ignored the target point ``s``: every candidate then scored
  alike and the demonstrated target won 5-20 % of the ticks. The recogniser needs a
  feature *unlike* the demonstrations (a wrong candidate's) to score near the prior mean
  0, which only short length scales give; the evidence never sees such features. Measured
  on the 48-run demonstration set (``autonomy/models/README.md``; train on even runs, pick
  rate on the odd ones, 10 nearest candidates, angle encoded as plain (cos, sin), capacity
  250): cap 1.0 std 65 %, 0.5 std 75 %, 0.3 std 79 % (in-sample: 100 std 10 %, 3 std
  28 %, 1 std 63 %, 0.5 std 83 %; the shipped model, with the speed-scaled encoding of
  ``autonomy.features``, 82 %). The evidence
  optimum lies on the cap in almost every column; 0.5 is chosen over 0.3 to keep some
  generalisation to task types not demonstrated (thesis Sec. 7.4.2).
- Near-duplicate inputs. Every full update adds ``e e^T / gamma`` to ``Q``; with the
  novelty threshold at 1e-6 of the signal variance a near-duplicate BV made ``Q`` grow to
  1e13 within a few hundred updates on the demonstrations, rounding then drove ``gamma``
  negative and the model overflowed to NaN. The threshold is 1e-4 (``Q`` and the Gram
  matrix's condition number stay bounded, C&O's "gamma test"), and a ``gamma`` that rounding
  made negative -- impossible in exact arithmetic, it is a Schur complement -- triggers an
  immediate re-conditioning of ``Q`` before the update is decided.
- The noise floor matters: with +-1 labels of well-separated clusters the
  evidence drives the noise towards zero (the labels are then a deterministic function of
  the features), and such a near-noiseless posterior is poorly represented by a sparse
  basis -- measured on a 3-cluster toy problem at capacity 60 of 450 points, training RMSE
  0.4-0.7 with noise 1e-4 (signal 3.6) against 0.13-0.15 with noise 1e-2.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.linalg import blas, cho_factor, cho_solve, lapack
from scipy.optimize import minimize

_TINY = 1e-300
_MIN_ALLOC = 16
_REFINE_BLOCK = 4096  # observations per kernel block in SparseOnlineGP.refine
MAX_LENGTH_SCALE = 0.5  # upper bound of a length scale, in standard deviations of its column
NOVELTY_TOL = 1e-4  # relative to the signal variance; below it a point is projected


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


class SparseOnlineGP:
    """Sparse Online GP regression with Gaussian noise (Csató & Opper 2002).

    Parameters
    ----------
    capacity : int
        Maximum number of basis vectors (500 in the thesis, Sec. 7.3).
    length_scales : numpy.ndarray
        (d,) SE-ARD length scales, in the inputs' units.
    signal_var : float
        Kernel signal variance ``k(x, x)``.
    noise_var : float
        Observation noise variance ``sigma^2`` of Eq. (5.4).
    novelty_tol : float
        A point whose novelty ``gamma`` is below this (in units of the kernel) is
        projected onto the current BVs instead of becoming a BV.
    recondition_every : int
        Recompute the inverse Gram matrix ``Q`` from scratch every this many updates.

    Attributes
    ----------
    n_basis_ : int
        Number of basis vectors.
    basis_ : numpy.ndarray
        (b, d) the basis vectors, in the inputs' units.
    alpha_ : numpy.ndarray
        (b,) mean coefficients.
    C_ : numpy.ndarray
        (b, b) symmetric covariance correction (negative semi-definite for a GP posterior).
    Q_ : numpy.ndarray
        (b, b) inverse Gram matrix of the basis vectors.
    n_updates_ : int
        Observations absorbed since the last reset.
    """

    def __init__(
        self,
        *,
        capacity: int = 500,
        length_scales: np.ndarray,
        signal_var: float,
        noise_var: float,
        novelty_tol: float = NOVELTY_TOL,
        recondition_every: int = 1000,
    ) -> None:
        ls = np.array(length_scales, dtype=float).reshape(-1)
        if ls.size < 1 or not np.all(np.isfinite(ls)) or np.any(ls <= 0):
            raise ValueError(f"length_scales: must be finite and > 0, got {length_scales!r}")
        if not (np.isfinite(signal_var) and signal_var > 0):
            raise ValueError(f"signal_var: must be finite and > 0, got {signal_var!r}")
        if not (np.isfinite(noise_var) and noise_var > 0):
            raise ValueError(f"noise_var: must be finite and > 0, got {noise_var!r}")
        if int(capacity) != capacity or capacity < 1:
            raise ValueError(f"capacity: must be an integer >= 1, got {capacity!r}")
        if not (novelty_tol >= 0):
            raise ValueError(f"novelty_tol: must be >= 0, got {novelty_tol!r}")
        if int(recondition_every) != recondition_every or recondition_every < 1:
            raise ValueError(
                f"recondition_every: must be an integer >= 1, got {recondition_every!r}"
            )
        self.capacity = int(capacity)
        self.length_scales = ls
        self.signal_var = float(signal_var)
        self.noise_var = float(noise_var)
        self.novelty_tol = float(novelty_tol)
        self.recondition_every = int(recondition_every)
        self._reset()

    # ------------------------------------------------------------------ state
    def _reset(self) -> None:
        self._b = 0
        self.n_updates_ = 0
        self._allocate(min(self.capacity + 1, _MIN_ALLOC))

    def _allocate(self, size: int) -> None:
        d = self.length_scales.size
        self._dense_C: np.ndarray | None = None  # caches for batch prediction
        self._bv_norms: np.ndarray | None = None
        self._size = size
        self._Xs = np.zeros((size, d))  # BVs divided by the length scales
        self._alpha = np.zeros(size)
        self._C = np.zeros((size, size), order="F")  # upper triangle used
        self._Q = np.zeros((size, size), order="F")  # upper triangle used
        self._k = np.zeros(size)
        self._col_q = np.zeros(size)
        self._col_c = np.zeros(size)

    def _grow_to(self, size: int) -> None:
        b = self._b
        Xs, alpha, C, Q = self._Xs, self._alpha, self._C, self._Q
        self._allocate(size)
        self._Xs[:b] = Xs[:b]
        self._alpha[:b] = alpha[:b]
        self._C[:b, :b] = C[:b, :b]
        self._Q[:b, :b] = Q[:b, :b]

    def _ensure_room(self) -> None:
        # Invariant: one free slot beyond the BVs, for the next full update.
        if self._b + 1 > self._size:
            self._grow_to(_alloc_size(self._b, self.capacity))

    @property
    def n_basis_(self) -> int:
        return self._b

    @property
    def basis_(self) -> np.ndarray:
        return self._Xs[: self._b] * self.length_scales

    @property
    def alpha_(self) -> np.ndarray:
        return self._alpha[: self._b].copy()

    @property
    def C_(self) -> np.ndarray:
        return _symmetric(self._C, self._b)

    @property
    def Q_(self) -> np.ndarray:
        return _symmetric(self._Q, self._b)

    # ----------------------------------------------------------------- kernel
    def _scaled(self, X: np.ndarray) -> np.ndarray:
        return np.asarray(X, dtype=float) / self.length_scales

    def _kernel_vector(self, xs: np.ndarray) -> np.ndarray:
        """k between the BVs and one scaled input, zero beyond the BVs; (size,)."""
        b = self._b
        k = self._k
        diff = self._Xs[:b] - xs
        np.exp(-0.5 * np.einsum("ij,ij->i", diff, diff), out=k[:b])  # Eq. (5.7)
        k[:b] *= self.signal_var
        k[b:] = 0.0
        return k

    # ----------------------------------------------------------------- update
    def update(self, x: np.ndarray, y: float) -> SparseOnlineGP:
        """Absorb one observation online (C&O Sec. 3).

        Parameters
        ----------
        x : numpy.ndarray
            (d,) input.
        y : float
            Observed target.

        Returns
        -------
        SparseOnlineGP
            self.
        """
        x = np.asarray(x, dtype=float)
        if x.shape != self.length_scales.shape:
            raise ValueError(f"x: expected shape {self.length_scales.shape}, got {x.shape}")
        y = float(y)
        if not (np.isfinite(y) and np.isfinite(x).all()):
            raise ValueError("x, y: must be finite (no NaN or inf)")
        self._update_scaled(x / self.length_scales, y)
        return self

    def _update_scaled(self, xs: np.ndarray, y: float) -> None:
        self._dense_C = None
        self._bv_norms = None
        b = self._b
        k = self._kernel_vector(xs)
        kss = self.signal_var
        # Current predictive moments at x.
        ck = blas.dsymv(1.0, self._C, k)
        mean = float(k[:b] @ self._alpha[:b])  # Eq. (5.6)
        s2 = max(kss + float(k[:b] @ ck[:b]), 0.0)  # latent variance, clamped
        denom = s2 + self.noise_var
        q = (y - mean) / denom  # C&O: first derivative of the log-likelihood
        r = -1.0 / denom  # C&O: second derivative
        # Projection onto the current BVs and novelty.
        e_hat = blas.dsymv(1.0, self._Q, k)
        gamma = kss - float(k[:b] @ e_hat[:b])
        if gamma < 0.0:
            # A Schur complement cannot be negative: Q has drifted. Rebuild it first.
            self._recondition()
            e_hat = blas.dsymv(1.0, self._Q, k)
            gamma = kss - float(k[:b] @ e_hat[:b])
        weakest = -1  # the BV to delete after adding x, if at capacity
        if gamma >= self.novelty_tol * kss and b == self.capacity:
            weakest = self._weakest(ck, e_hat, q, r, gamma)
        if gamma < self.novelty_tol * kss:
            # Reduced update (C&O Sec. 3): the projected observation, treated exactly.
            eta = 1.0 / (1.0 + r * max(gamma, 0.0))
            self._reduced_update(ck, e_hat, q * eta, r * eta)
        elif weakest == b:
            # At capacity and x itself would be deleted at once: adding x and deleting it
            # again with C&O's equations equals the reduced update with eta = 1, at a
            # third of the cost (no change to Q, no deletion).
            self._reduced_update(ck, e_hat, q, r)
        else:
            # Full update (C&O Sec. 3): x becomes BV number b.
            s = ck
            s[b] = 1.0
            self._alpha += q * s
            self._C = blas.dsyr(r, s, a=self._C, overwrite_a=1)
            e_hat[b] = -1.0
            self._Q = blas.dsyr(1.0 / gamma, e_hat, a=self._Q, overwrite_a=1)
            self._Xs[b] = xs
            self._b = b + 1
            if weakest >= 0:
                self._delete(weakest)
            self._ensure_room()
        self.n_updates_ += 1
        if self.n_updates_ % self.recondition_every == 0:
            self._recondition()

    def _reduced_update(self, ck: np.ndarray, e_hat: np.ndarray, q: float, r: float) -> None:
        s = ck
        s += e_hat  # s = C k + e_hat
        self._alpha += q * s
        self._C = blas.dsyr(r, s, a=self._C, overwrite_a=1)

    def _weakest(self, ck: np.ndarray, e_hat: np.ndarray, q: float, r: float, gamma: float) -> int:
        """Index of the lowest KL score once x were added as BV number b, in O(b)."""
        b = self._b
        alpha = np.empty(b + 1)
        alpha[:b] = self._alpha[:b] + q * ck[:b]
        alpha[b] = q
        diag = np.empty(b + 1)
        diag[:b] = (
            np.diagonal(self._Q)[:b]
            + e_hat[:b] ** 2 / gamma
            + np.diagonal(self._C)[:b]
            + r * ck[:b] ** 2
        )
        diag[b] = 1.0 / gamma + r
        return int(np.argmin(alpha**2 / np.maximum(diag, _TINY)))  # C&O KL score

    def _delete(self, i: int) -> None:
        """Remove BV ``i`` with C&O's deletion equations, then compact.

        With ``a* = alpha_i``, ``c* = C_ii``, ``q* = Q_ii`` and ``C*``, ``Q*`` the i-th
        columns::

            alpha <- alpha - a* Q* / q*
            C     <- C + c* Q* Q*^T / q*^2 - (Q* C*^T + C* Q*^T) / q*
            Q     <- Q - Q* Q*^T / q*

        Applied to the full arrays these zero row and column i (up to rounding, which is
        then cleared), so the remaining block is exactly the reduced model.
        """
        b = self._b
        col_q = _sym_column(self._Q, i, b, self._col_q)
        col_c = _sym_column(self._C, i, b, self._col_c)
        a_s = self._alpha[i]
        c_s = col_c[i]
        q_s = col_q[i]
        self._alpha -= (a_s / q_s) * col_q
        # C + c* Q*Q*^T/q*^2 - (Q*C*^T + C*Q*^T)/q* as one symmetric rank-2 update.
        w = col_c - (c_s / (2.0 * q_s)) * col_q
        self._C = blas.dsyr2(-1.0 / q_s, col_q, w, a=self._C, overwrite_a=1)
        self._Q = blas.dsyr(-1.0 / q_s, col_q, a=self._Q, overwrite_a=1)
        last = b - 1
        for U in (self._C, self._Q):
            U[: i + 1, i] = 0.0
            U[i, i:b] = 0.0
            if i < last:
                # Move the last BV into slot i (upper triangle only).
                col = U[:last, last].copy()
                U[:i, i] = col[:i]
                U[i, i + 1 : last] = col[i + 1 : last]
                U[i, i] = U[last, last]
                U[: last + 1, last] = 0.0
        self._alpha[i] = self._alpha[last]
        self._alpha[last] = 0.0
        self._Xs[i] = self._Xs[last]
        self._Xs[last] = 0.0
        self._b = last

    def _gram(self) -> np.ndarray:
        """The BVs' Gram matrix, (b, b)."""
        Xb = self._Xs[: self._b]
        return se_ard_kernel(Xb, Xb, length_scales=np.ones(Xb.shape[1]), signal_var=self.signal_var)

    def _recondition(self, K: np.ndarray | None = None) -> None:
        """Recompute Q as the inverse Gram matrix ``K`` of the BVs (computed here unless
        given) by Cholesky with jitter."""
        b = self._b
        if b == 0:
            return
        K = self._gram() if K is None else K
        factor = _cholesky_with_jitter(K, 1e-10 * self.signal_var)
        if factor is None:  # pragma: no cover - a Gram matrix with jitter 1e2 * signal_var
            return
        Qb = cho_solve(factor, np.eye(b), check_finite=False)
        self._Q[:b, :b] = np.triu(Qb)

    def _checked(self, X: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``X`` (n, d) and ``y`` (n,) as finite float arrays; ValueError naming the bad one."""
        X = np.asarray(X, dtype=float)
        y = np.asarray(y, dtype=float).reshape(-1)
        d = self.length_scales.size
        if X.ndim != 2 or X.shape[1] != d:
            raise ValueError(f"X: expected shape (n, {d}), got {X.shape}")
        if y.shape[0] != X.shape[0]:
            raise ValueError(f"y: expected {X.shape[0]} targets, got {y.shape[0]}")
        if not (np.all(np.isfinite(X)) and np.all(np.isfinite(y))):
            raise ValueError("X, y: must be finite (no NaN or inf)")
        return X, y

    def fit(self, X: np.ndarray, y: np.ndarray) -> SparseOnlineGP:
        """Reset, then absorb the rows of ``X`` (n, d) with targets ``y`` (n,) in order."""
        X, y = self._checked(X, y)
        self._reset()
        Xs = X / self.length_scales
        for j in range(X.shape[0]):
            self._update_scaled(Xs[j], float(y[j]))
        return self

    def refine(self, X: np.ndarray, y: np.ndarray) -> SparseOnlineGP:
        """Re-estimate ``alpha`` and ``C`` from the observations ``(X, y)`` on the current
        basis vectors: the projected-process posterior.

        The online pass (:meth:`fit`) chooses the BVs, but each point it saw before the
        basis settled was absorbed against the basis of that moment and the information
        of a deleted BV survives only as its projection, so one pass is order-dependent.
        Sweeping C&O's update over the data again and again converges, for the Gaussian
        likelihood, to the posterior of every observation projected onto the final basis
        (Csató 2002, the sparse EP of his thesis Ch. 4; Seeger et al. 2003's projected
        process). That fixed point, in closed form, with ``Kbb`` the BVs' Gram matrix and
        ``Knb`` the kernel between the observations and the BVs::

            M     = noise_var Kbb + Knb^T Knb
            alpha = M^-1 Knb^T y
            C     = noise_var M^-1 - Kbb^-1          (Q = Kbb^-1 is recomputed)

        With every observation a BV this is the full GP posterior again. It costs
        O(n b^2) in level-3 BLAS (``Knb`` in row blocks), far less than the online pass
        at the same capacity. The basis is unchanged; later :meth:`update` calls go on
        from the refined posterior.

        Parameters
        ----------
        X : numpy.ndarray
            (n, d) the observations' inputs (normally those given to :meth:`fit`).
        y : numpy.ndarray
            (n,) their targets.

        Returns
        -------
        SparseOnlineGP
            self.
        """
        X, y = self._checked(X, y)
        b = self._b
        if b == 0 or X.shape[0] == 0:
            return self
        self._dense_C = None
        self._bv_norms = None
        Xs = X / self.length_scales
        Kbb = self._gram()
        M = self.noise_var * Kbb
        rhs = np.zeros(b)
        for start in range(0, X.shape[0], _REFINE_BLOCK):
            block = slice(start, start + _REFINE_BLOCK)
            Knb = self._cross_kernel(Xs[block])
            M += Knb.T @ Knb
            rhs += Knb.T @ y[block]
        factor = _cholesky_with_jitter(M, 1e-12 * float(np.trace(M)) / b)
        if factor is None:  # pragma: no cover - M is a Gram matrix plus a ridge
            return self
        self._alpha[:b] = cho_solve(factor, rhs, check_finite=False)
        self._recondition(Kbb)
        C = self.noise_var * cho_solve(factor, np.eye(b), check_finite=False) - _symmetric(
            self._Q, b
        )
        self._C[:b, :b] = np.triu(C)
        return self

    # ---------------------------------------------------------------- predict
    def predict(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Predictive mean and variance of the targets.

        Parameters
        ----------
        X : numpy.ndarray
            (n, d) query inputs (a single (d,) input is treated as n = 1).

        Returns
        -------
        mean : numpy.ndarray
            (n,) predictive mean, Eq. (5.6).
        var : numpy.ndarray
            (n,) predictive variance including the noise, Eq. (5.9); >= noise_var.
        """
        Xs = self._scaled_queries(X)
        n, b = Xs.shape[0], self._b
        if b == 0:
            return np.zeros(n), np.full(n, self.signal_var + self.noise_var)
        if n == 1:
            k = self._kernel_vector(Xs[0])
            ck = blas.dsymv(1.0, self._C, k)
            mean = np.array([k[:b] @ self._alpha[:b]])  # Eq. (5.6)
            lat = np.array([self.signal_var + k[:b] @ ck[:b]])
        else:
            # Dense symmetric C, cached until the next update: one GEMM per chunk beats
            # BLAS symm on the thin query blocks of the run-time tick.
            if self._dense_C is None:
                self._dense_C = _symmetric(self._C, b)
            mean = np.empty(n)
            lat = np.empty(n)
            for start in range(0, n, 2048):
                K = self._cross_kernel(Xs[start : start + 2048])
                mean[start : start + 2048] = K @ self._alpha[:b]  # Eq. (5.6)
                lat[start : start + 2048] = self.signal_var + np.einsum(
                    "ij,ij->i", K @ self._dense_C, K
                )
        var = np.maximum(lat, 0.0) + self.noise_var  # Eq. (5.9), clamped
        return mean, var

    def predict_mean(self, X: np.ndarray) -> np.ndarray:
        """Predictive mean only (Eq. 5.6), O(n b): all that the score (5.8) needs.

        Parameters
        ----------
        X : numpy.ndarray
            (n, d) query inputs (a single (d,) input is treated as n = 1).

        Returns
        -------
        numpy.ndarray
            (n,) predictive mean, equal to ``predict(X)[0]``.
        """
        Xs = self._scaled_queries(X)
        if self._b == 0:
            return np.zeros(Xs.shape[0])
        return self._cross_kernel(Xs) @ self._alpha[: self._b]  # Eq. (5.6)

    def _scaled_queries(self, X: np.ndarray) -> np.ndarray:
        X = np.atleast_2d(np.asarray(X, dtype=float))
        d = self.length_scales.size
        if X.ndim != 2 or X.shape[1] != d:
            raise ValueError(f"X: expected shape (n, {d}), got {X.shape}")
        return X / self.length_scales

    def _cross_kernel(self, Xs: np.ndarray) -> np.ndarray:
        """Kernel between scaled queries (n, d) and the BVs, (n, b)."""
        b = self._b
        if self._bv_norms is None:
            self._bv_norms = np.einsum("ij,ij->i", self._Xs[:b], self._Xs[:b])
        sq = np.einsum("ij,ij->i", Xs, Xs)[:, None] + self._bv_norms - 2.0 * (Xs @ self._Xs[:b].T)
        return self.signal_var * np.exp(-0.5 * np.maximum(sq, 0.0))  # Eq. (5.7)

    # -------------------------------------------------------------------- I/O
    def to_dict(self) -> dict[str, Any]:
        """Settings and learned arrays, for a model file (numpy arrays and scalars)."""
        return {
            "capacity": self.capacity,
            "length_scales": self.length_scales.copy(),
            "signal_var": self.signal_var,
            "noise_var": self.noise_var,
            "novelty_tol": self.novelty_tol,
            "recondition_every": self.recondition_every,
            "n_updates": int(self.n_updates_),
            "basis": self.basis_,
            "alpha": self.alpha_,
            "C": self.C_,
            "Q": self.Q_,
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> SparseOnlineGP:
        """Rebuild a model from :meth:`to_dict`; ValueError naming a malformed field."""
        required = (
            "capacity",
            "length_scales",
            "signal_var",
            "noise_var",
            "novelty_tol",
            "recondition_every",
            "n_updates",
            "basis",
            "alpha",
            "C",
            "Q",
        )
        for key in required:
            if key not in d:
                raise ValueError(f"sparse online GP: missing field '{key}'")
        try:
            model = cls(
                capacity=int(d["capacity"]),
                length_scales=np.asarray(d["length_scales"], dtype=float),
                signal_var=float(d["signal_var"]),
                noise_var=float(d["noise_var"]),
                novelty_tol=float(d["novelty_tol"]),
                recondition_every=int(d["recondition_every"]),
            )
        except (TypeError, ValueError) as exc:
            raise ValueError(f"sparse online GP: bad settings: {exc}") from exc
        dim = model.length_scales.size
        basis = np.asarray(d["basis"], dtype=float).reshape(-1, dim)
        b = basis.shape[0]
        alpha = np.asarray(d["alpha"], dtype=float)
        C = np.asarray(d["C"], dtype=float)
        Q = np.asarray(d["Q"], dtype=float)
        if b > model.capacity:
            raise ValueError(f"sparse online GP: 'basis' has {b} rows, above capacity")
        for name, arr, shape in (("alpha", alpha, (b,)), ("C", C, (b, b)), ("Q", Q, (b, b))):
            if arr.shape != shape:
                raise ValueError(
                    f"sparse online GP: '{name}' must have shape {shape}, got {arr.shape}"
                )
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"sparse online GP: '{name}' must be finite")
        if not np.all(np.isfinite(basis)):
            raise ValueError("sparse online GP: 'basis' must be finite")
        model._allocate(_alloc_size(b, model.capacity))
        model._b = b
        model._Xs[:b] = basis / model.length_scales
        model._alpha[:b] = alpha
        model._C[:b, :b] = np.triu(C)
        model._Q[:b, :b] = np.triu(Q)
        model.n_updates_ = int(d["n_updates"])
        return model


def _alloc_size(b: int, capacity: int) -> int:
    """Storage size for b BVs plus one free slot: 16, 32, 64, ... capped at capacity + 1."""
    size = _MIN_ALLOC
    while size < b + 1:
        size *= 2
    return min(size, capacity + 1)


def _cholesky_with_jitter(A: np.ndarray, jitter: float) -> tuple[np.ndarray, bool] | None:
    """``cho_factor`` of ``A + jitter I``, the jitter raised tenfold (12 times at most)
    until it factors; None if it never does."""
    eye = np.eye(A.shape[0])
    for _ in range(12):
        try:
            return cho_factor(A + jitter * eye, lower=False, check_finite=False)
        except np.linalg.LinAlgError:
            jitter *= 10.0
    return None


def _symmetric(U: np.ndarray, b: int) -> np.ndarray:
    """The (b, b) symmetric matrix whose upper triangle is stored in U."""
    up = np.triu(U[:b, :b])
    return up + np.triu(up, 1).T


def _sym_column(U: np.ndarray, i: int, b: int, out: np.ndarray) -> np.ndarray:
    """Column i of the symmetric matrix stored as upper triangle U, zero beyond b."""
    out[:i] = U[:i, i]
    out[i:b] = U[i, i:b]
    out[b:] = 0.0
    return out


# ------------------------------------------------------------------ hyperparameters
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


def fit_hyperparameters(
    X: np.ndarray,
    y: np.ndarray,
    *,
    rng: np.random.Generator,
    max_points: int = 600,
    restarts: int = 3,
    max_length_scale: float = MAX_LENGTH_SCALE,
) -> tuple[np.ndarray, float, float]:
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
        Upper bound of the length scales in standard deviations of their columns (see
        the module docstring for why it is short).

    Returns
    -------
    length_scales : numpy.ndarray
        (d,) SE-ARD length scales.
    signal_var : float
        Signal variance.
    noise_var : float
        Noise variance.
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
    return np.exp(best_theta[:d]), float(np.exp(best_theta[d])), float(np.exp(best_theta[d + 1]))
