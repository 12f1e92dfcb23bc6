"""The thesis's recogniser (Ch. 5-6): Eqs. (5.6), (5.8), (5.10) over the candidates and
the motion primitives, from the arrays of a fitted SOGP classifier; the contextual mode's
``recogniser = "thesis"``, and the scores the kind-and-time recogniser builds on
(:mod:`autonomy.kind_time`)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.special import ndtr

from autonomy import _tick_kernels
from autonomy.sogp_classifier import argmax_finite


class Recogniser:
    """Eqs. (5.6), (5.8), (5.10) over candidates x clusters from the arrays of a fitted SOGP
    classifier (``SOGPClassifier.to_dict()``; the GPs' ``Q`` is not needed).

    Equivalent to :func:`autonomy.sogp_classifier.recognise`, but computes the predictive
    variance only for the winning candidate and cluster. The clusters' basis vectors are
    stacked at load time (zero-padded to the largest basis, padded rows with ``alpha = 0``
    and zero rows and columns of ``C``, which add exact zeros), so one tick evaluates the
    kernels of all clusters in one compiled loop (:func:`autonomy._tick_kernels.sogp_kernels`)
    and the means, the winner and its variance in another
    (:func:`autonomy._tick_kernels.recognise`, BLAS's summation orders written out); the
    numpy arithmetic they replaced is kept for a single candidate.
    """

    def __init__(self, sogp: dict[str, Any]) -> None:
        self.classes_ = np.asarray(sogp["classes"]).copy()
        models = list(sogp["models"])
        c = len(models)
        b = max((len(gp["alpha"]) for gp in models), default=0)
        d = int(np.asarray(models[0]["length_scales"]).size) if c else 0
        self.ls_ = np.ones((c, 1, d))  # (c, 1, d) length scales
        self.xs_ = np.zeros((c, b, d))  # (c, b, d) basis / length scales
        self.xs2_ = np.zeros((c, b, 1))  # (c, b, 1) squared norms of xs_
        self.alpha_ = np.zeros((c, 1, b))  # (c, 1, b)
        self.C_ = []  # per cluster (b_j, b_j)
        self.n_basis_ = []
        self.sf2_ = np.zeros((c, 1, 1))
        self.noise_ = np.zeros(c)
        for j, gp in enumerate(models):
            ls = np.asarray(gp["length_scales"], dtype=float)
            xs = np.asarray(gp["basis"], dtype=float) / ls
            n = len(xs)
            self.ls_[j, 0] = ls
            self.xs_[j, :n] = xs
            self.xs2_[j, :n, 0] = (xs * xs).sum(axis=1)
            self.alpha_[j, 0, :n] = np.asarray(gp["alpha"], dtype=float)
            self.C_.append(np.asarray(gp["C"], dtype=float))
            self.n_basis_.append(n)
            self.sf2_[j] = float(gp["signal_var"])
            self.noise_[j] = float(gp["noise_var"])
        # the same as contiguous (c, d), (c, d, b), (c, b), (c,) arrays for the kernels
        self.ls2_ = np.ascontiguousarray(self.ls_[:, 0, :])
        self.xs_t_ = np.ascontiguousarray(self.xs_.transpose(0, 2, 1))  # (c, d, b)
        self.xs2v_ = np.ascontiguousarray(self.xs2_[:, :, 0])
        self.sf2v_ = np.ascontiguousarray(self.sf2_[:, 0, 0])
        self.alphav_ = np.ascontiguousarray(self.alpha_[:, 0, :])  # (c, b)
        self.n_basisv_ = np.array(self.n_basis_, dtype=np.int64)  # (c,)
        self.Ct_ = np.zeros((c, b, b))  # (c, b, b) the C_ transposed, zero-padded
        for j, cj in enumerate(self.C_):
            self.Ct_[j, : len(cj), : len(cj)] = cj.T
        self.work_ = np.empty((6, b))  # the winner's kernel column, C k, 4 lanes

    def __call__(self, Z: np.ndarray) -> tuple[int, int, float, np.ndarray]:
        """Recognise over the rows of ``Z`` (m, d), standardised encoded features.

        Returns
        -------
        best_candidate : int
            Row of ``Z`` with the largest finite posterior mean over all clusters (5.8);
            -1 if no mean is finite.
        best_cluster : int
            Its cluster id (-1 if none).
        beta : float
            ``Phi(mu / sqrt(var))`` of the winner (5.10); 0 if none.
        mean : numpy.ndarray
            (m, c) posterior means (5.6).
        """
        Z = np.ascontiguousarray(np.atleast_2d(np.asarray(Z, dtype=float)))
        if len(Z) > 1:
            return self._many(Z)
        if len(Z) == 1:  # BLAS computes xs @ a.T as a gemv here, in another order
            a = Z / self.ls_  # (c, 1, d)
            sq = self.xs2_ + (a * a).sum(axis=2)[:, None, :]
            sq -= 2.0 * (self.xs_ @ a.transpose(0, 2, 1))  # (c, b, 1)
            np.maximum(sq, 0.0, out=sq)
            sq *= -0.5
            K = np.exp(sq, out=sq)
            K *= self.sf2_  # Eq. (5.7)
        else:
            K = np.empty((len(self.n_basis_), self.xs_.shape[1], 0))
        mean = (self.alpha_ @ K)[:, 0, :].T  # (m, c), Eq. (5.6)
        i, j = argmax_finite(mean)  # Eq. (5.8), never a non-finite score
        if i < 0:
            return -1, -1, 0.0, mean
        k = K[j, : self.n_basis_[j], i]
        sf2 = float(self.sf2_[j, 0, 0])
        var = max(sf2 + float(k @ (self.C_[j] @ k)), 0.0) + float(self.noise_[j])  # Eq. (5.9)
        beta = float(ndtr(mean[i, j] / math.sqrt(var)))  # Eq. (5.10)
        if not math.isfinite(beta):
            beta = 0.0
        return i, int(self.classes_[j]), beta, mean

    def means(self, Z: np.ndarray) -> np.ndarray:
        """The posterior means (m, c) of Eq. (5.6) alone (no winner, no variance): what
        the kind-and-time recogniser (autonomy.kind_time) builds on; ``Z`` as in
        :meth:`__call__`. Equal to ``self(Z)[3]`` up to the sums' order."""
        Z = np.ascontiguousarray(np.atleast_2d(np.asarray(Z, dtype=float)))
        if len(Z) < 2:
            return self(Z)[3]
        c, b = self.alphav_.shape
        K = np.empty((c, b, len(Z)))
        _tick_kernels.sogp_kernels(Z, self.ls2_, self.xs_t_, self.xs2v_, self.sf2v_, K)
        mean = np.empty((c, len(Z)))
        for j in range(c):
            _tick_kernels.gemv_rows(K[j], self.alphav_[j], mean[j])  # Eq. (5.6)
        return mean.T

    def _many(self, Z: np.ndarray) -> tuple[int, int, float, np.ndarray]:
        """:meth:`__call__` for ``Z`` (m, d) C-contiguous float64, m >= 2: the kernels
        (:func:`autonomy._tick_kernels.sogp_kernels`, :func:`autonomy._tick_kernels.recognise`)
        repeat the numpy arithmetic, BLAS's products included; ndtr is scipy's."""
        c, b = self.alphav_.shape
        K = np.empty((c, b, len(Z)))
        _tick_kernels.sogp_kernels(Z, self.ls2_, self.xs_t_, self.xs2v_, self.sf2v_, K)
        mean = np.empty((c, len(Z)))
        i, j, var = _tick_kernels.recognise(
            K, self.alphav_, self.n_basisv_, self.Ct_, self.sf2v_, self.noise_, mean, self.work_
        )
        if i < 0:
            return -1, -1, 0.0, mean.T
        beta = float(ndtr(mean[j, i] / math.sqrt(var)))  # Eq. (5.10)
        if not math.isfinite(beta):
            beta = 0.0
        return i, int(self.classes_[j]), beta, mean.T
