"""Sparse Online Gaussian Process regression (Csató & Opper 2002, "Sparse on-line Gaussian
processes", Neural Computation 14(3), Sec. 3-4, "C&O" below; thesis Sec. 5.2, 7.3).

The posterior of a zero-mean GP with squared-exponential ARD kernel and Gaussian noise
(Eq. 5.4-5.7, 5.9) over at most ``capacity`` basis vectors, absorbing one observation at
a time; with room for every point it is the full GP posterior. Hyperparameters:
:mod:`autonomy.gp_hyperparameters`. Choices where the thesis is silent:
docs/decisions.md.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.linalg import blas, cho_solve

from autonomy.gp_kernel import cholesky_with_jitter, se_ard_kernel

_TINY = 1e-300
_MIN_ALLOC = 16
_REFINE_BLOCK = 4096  # observations per kernel block in SparseOnlineGP.refine
MAX_LENGTH_SCALE = 100.0  # bound of a length scale [std of its column]: a numerical guard
NOVELTY_TOL = 1e-4  # relative to the signal variance; below it a point is projected


class SparseOnlineGP:
    """Sparse Online GP regression with Gaussian noise (Csató & Opper 2002).

    The posterior is kept in C&O's parametrisation over the basis vectors (BVs)::

        mean(x)  = k_x^T alpha                            # Eq. (5.6)
        var(x)   = k(x, x) + k_x^T C k_x + noise_var      # Eq. (5.9)

    with ``k_x`` the kernel between the BVs and ``x`` and ``Q`` the inverse Gram matrix of
    the BVs. One observation ``(x, y)`` is absorbed exactly by C&O's rank-one updates:
    ``q = (y - m_x) / (s2_x + noise_var)``, ``r = -1 / (s2_x + noise_var)`` with the
    predictive mean ``m_x`` and latent variance ``s2_x`` at ``x``; projection
    ``e_hat = Q k_x`` and novelty ``gamma = k(x, x) - k_x^T e_hat``; when
    ``gamma < novelty_tol * k(x, x)`` (relative to the signal variance, so independent of
    the targets' units) the reduced update ``s = C k_x + e_hat`` without a new BV, else
    the full update ``s = (C k_x, 1)`` (alpha, C and Q grow by one); then
    ``alpha += q s``, ``C += r s s^T``, ``Q += (e_hat, -1)(e_hat, -1)^T / gamma``. Above
    capacity the BV with the smallest score ``alpha_i^2 / (Q_ii + C_ii)`` is deleted
    (:meth:`_delete`).

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
        factor = cholesky_with_jitter(K, 1e-10 * self.signal_var)
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
        factor = cholesky_with_jitter(M, 1e-12 * float(np.trace(M)) / b)
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
