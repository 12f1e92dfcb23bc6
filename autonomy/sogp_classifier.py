"""One-vs-all SOGP classifier of motion clusters (thesis Ch. 5, Sec. 6.2.2, 6.2.3, 7.3).

For every motion cluster ``c`` one :class:`~autonomy.sogp.SparseOnlineGP` regresses the
labels ``t = +1`` (the cluster's own points) and ``t = -1`` (all others) with Gaussian
noise (Eqs. 5.4-5.6); its predictive mean and variance (5.6, 5.9) give the confidence
``p(t >= 0) = Phi(mu / sigma)`` (5.10). At run time every candidate semantic component
yields a query feature; the winner is the largest posterior mean over all clusters and
candidates (5.8), and its confidence is the arbitration factor ``beta`` (Sec. 5.2, 6.2.3).
Introspection uses the normalised entropy of the label distribution (Sec. 7.3, Eq. 7.7).
Inputs are used as given; the caller standardises them (``autonomy.features``). Choices
where the thesis is silent: docs/decisions.md.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.special import ndtr

from autonomy import _tick_kernels
from autonomy.gp_hyperparameters import fit_hyperparameters
from autonomy.sogp import MAX_LENGTH_SCALE, SparseOnlineGP


class SOGPClassifier:
    """One-vs-all classifier with one Sparse Online GP per class (Ch. 5).

    Parameters
    ----------
    capacity : int
        Basis vectors per GP (500 in the thesis, Sec. 7.3).
    hyper_points : int
        Size of the class-balanced subsample on which the evidence is maximised.
    restarts : int
        L-BFGS-B runs per class for the hyperparameters (see
        :func:`autonomy.gp_hyperparameters.fit_hyperparameters`).
    max_length_scale : float
        Upper bound of the length scales, in standard deviations of the inputs.
    refine : bool
        After the online pass, re-estimate every GP's posterior from all its training
        points on the basis the pass chose (:meth:`SparseOnlineGP.refine`).

    Attributes
    ----------
    classes_ : numpy.ndarray
        (c,) the cluster ids, sorted; column j of every output belongs to ``classes_[j]``.
    models_ : list of SparseOnlineGP
        (c,) the one-vs-all regressors.
    hyperparameters_ : list of Hyperparameters
        (c,) the evidence optimum each GP was built with (not saved in a model file).
    """

    classes_: np.ndarray
    models_: list[SparseOnlineGP]

    def __init__(
        self,
        *,
        capacity: int = 500,
        hyper_points: int = 600,
        restarts: int = 3,
        max_length_scale: float = MAX_LENGTH_SCALE,
        refine: bool = False,
    ) -> None:
        self.capacity = int(capacity)
        self.hyper_points = int(hyper_points)
        self.restarts = int(restarts)
        self.max_length_scale = float(max_length_scale)
        self.refine = bool(refine)

    def fit(
        self,
        X: np.ndarray,
        labels: np.ndarray,
        *,
        rng: np.random.Generator,
        negatives: np.ndarray | None = None,
    ) -> SOGPClassifier:
        """Learn one GP per cluster on targets +1 (own cluster) / -1 (others).

        Parameters
        ----------
        X : numpy.ndarray
            (n, d) training features (standardised).
        labels : numpy.ndarray
            (n,) integer cluster ids.
        rng : numpy.random.Generator
            Subsample, optimiser restarts and the order of the online updates.
        negatives : numpy.ndarray, optional
            (k, d) "hard negatives": features that belong to no cluster (e.g. the other
            candidate components at a demonstrated tick), target -1 in *every* GP. They
            take part in the class-balanced evidence subsample as one extra class.

        Returns
        -------
        SOGPClassifier
            self.
        """
        X = np.asarray(X, dtype=float)
        labels = np.asarray(labels)
        if X.ndim != 2 or X.shape[0] < 2:
            raise ValueError(f"X: expected an (n, d) array with n >= 2, got shape {X.shape}")
        if labels.shape != (X.shape[0],):
            raise ValueError(f"labels: expected shape ({X.shape[0]},), got {labels.shape}")
        if not np.issubdtype(labels.dtype, np.integer):
            raise ValueError(f"labels: must be integer cluster ids, got dtype {labels.dtype}")
        if not np.all(np.isfinite(X)):
            raise ValueError("X: features must be finite (no NaN or inf)")
        self.classes_ = np.unique(labels)
        if negatives is not None and len(negatives) > 0:
            negatives = np.asarray(negatives, dtype=float)
            if negatives.ndim != 2 or negatives.shape[1] != X.shape[1]:
                raise ValueError(
                    f"negatives: expected shape (k, {X.shape[1]}), got {negatives.shape}"
                )
            if not np.all(np.isfinite(negatives)):
                raise ValueError("negatives: features must be finite (no NaN or inf)")
            none = int(self.classes_.min()) - 1  # a label no cluster has
            X = np.concatenate((X, negatives))
            labels = np.concatenate((labels, np.full(len(negatives), none, labels.dtype)))
        sub = balanced_subsample(labels, self.hyper_points, rng=rng)
        self.models_ = []
        self.hyperparameters_ = []
        for c in self.classes_:
            t = np.where(labels == c, 1.0, -1.0)  # one-vs-all targets, Eq. (5.1)
            hp = fit_hyperparameters(
                X[sub],
                t[sub],
                rng=rng,
                max_points=self.hyper_points,
                restarts=self.restarts,
                max_length_scale=self.max_length_scale,
            )
            self.hyperparameters_.append(hp)
            gp = SparseOnlineGP(
                capacity=self.capacity,
                length_scales=hp.length_scales,
                signal_var=hp.signal_var,
                noise_var=hp.noise_var,
            )
            order = rng.permutation(X.shape[0])
            gp.fit(X[order], t[order])
            if self.refine:
                gp.refine(X, t)
            self.models_.append(gp)
        return self

    def decision(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Posterior mean (5.6) and predictive variance (5.9) of every class.

        Parameters
        ----------
        X : numpy.ndarray
            (n, d) query features.

        Returns
        -------
        mean : numpy.ndarray
            (n, c) predictive means.
        var : numpy.ndarray
            (n, c) predictive variances including the noise.
        """
        self._check_fitted()
        X = np.atleast_2d(np.asarray(X, dtype=float))
        n, c = X.shape[0], self.classes_.size
        mean = np.empty((n, c))
        var = np.empty((n, c))
        for j, gp in enumerate(self.models_):
            mean[:, j], var[:, j] = gp.predict(X)
        return mean, var

    def scores(self, X: np.ndarray) -> np.ndarray:
        """Posterior means (5.6) of every class, without the variances; (n, c).

        Cheaper than :meth:`decision` (O(n b) per class instead of O(n b^2)); the
        recognition score (5.8) needs only these.
        """
        self._check_fitted()
        X = np.atleast_2d(np.asarray(X, dtype=float))
        return np.column_stack([gp.predict_mean(X) for gp in self.models_])

    def confidence(self, X: np.ndarray) -> np.ndarray:
        """``p(t_c >= 0) = Phi(mu_c / sigma_c)`` for every class (5.10); (n, c) in [0, 1]."""
        mean, var = self.decision(X)
        return ndtr(mean / np.sqrt(var))  # Eq. (5.10)

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """The confidences (5.10) normalised over the classes; (n, c), rows sum to 1."""
        conf = self.confidence(X)
        total = conf.sum(axis=1, keepdims=True)
        uniform = np.full_like(conf, 1.0 / conf.shape[1])
        return np.where(total > 0, conf / np.where(total > 0, total, 1.0), uniform)

    def predict(self, X: np.ndarray) -> np.ndarray:
        """The class with the largest posterior mean (5.8); (n,) cluster ids."""
        mean, _ = self.decision(X)
        return self.classes_[np.argmax(mean, axis=1)]

    def to_dict(self) -> dict[str, Any]:
        """Settings, classes and every GP's :meth:`SparseOnlineGP.to_dict`."""
        self._check_fitted()
        return {
            "capacity": self.capacity,
            "hyper_points": self.hyper_points,
            "restarts": self.restarts,
            "max_length_scale": self.max_length_scale,
            "refine": self.refine,
            "classes": self.classes_.copy(),
            "models": [gp.to_dict() for gp in self.models_],
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> SOGPClassifier:
        """Rebuild from :meth:`to_dict`; ValueError naming a malformed field."""
        for key in ("capacity", "hyper_points", "restarts", "classes", "models"):
            if key not in d:
                raise ValueError(f"SOGP classifier: missing field '{key}'")
        classes = np.asarray(d["classes"])
        if classes.ndim != 1 or classes.size < 1 or not np.issubdtype(classes.dtype, np.integer):
            raise ValueError("SOGP classifier: 'classes' must be a non-empty 1-D integer array")
        models = list(d["models"])
        if len(models) != classes.size:
            raise ValueError(
                f"SOGP classifier: 'models' has {len(models)} entries for {classes.size} classes"
            )
        out = cls(
            capacity=int(d["capacity"]),
            hyper_points=int(d["hyper_points"]),
            restarts=int(d["restarts"]),
            max_length_scale=float(d.get("max_length_scale", MAX_LENGTH_SCALE)),
            refine=bool(d.get("refine", False)),
        )
        out.classes_ = classes.copy()
        out.models_ = [SparseOnlineGP.from_dict(m) for m in models]
        dims = {gp.length_scales.size for gp in out.models_}
        if len(dims) != 1:
            raise ValueError("SOGP classifier: the class models disagree on the input dimension")
        return out

    def _check_fitted(self) -> None:
        if not hasattr(self, "models_"):
            raise RuntimeError("SOGPClassifier is not fitted; call fit() first")


def balanced_subsample(labels: np.ndarray, size: int, *, rng: np.random.Generator) -> np.ndarray:
    """Indices of a class-balanced subsample of at most ``size`` points.

    Every class gets an equal quota; a class smaller than its quota gives all its points
    and the remainder is shared out among the others.

    Parameters
    ----------
    labels : numpy.ndarray
        (n,) class ids.
    size : int
        Maximum subsample size.
    rng : numpy.random.Generator
        Draws the points within each class.

    Returns
    -------
    numpy.ndarray
        (min(n, size),) sorted indices into ``labels``.
    """
    labels = np.asarray(labels)
    n = labels.shape[0]
    if n <= size:
        return np.arange(n)
    classes, counts = np.unique(labels, return_counts=True)
    quota = np.zeros(classes.size, dtype=int)
    left = size
    open_ = np.ones(classes.size, dtype=bool)
    while left > 0 and open_.any():
        share = max(left // int(open_.sum()), 1)
        for j in np.flatnonzero(open_):
            take = min(share, counts[j] - quota[j], left)
            quota[j] += take
            left -= take
            if quota[j] == counts[j]:
                open_[j] = False
            if left == 0:
                break
    picks = [
        rng.choice(np.flatnonzero(labels == c), size=q, replace=False)
        for c, q in zip(classes, quota, strict=True)
        if q > 0
    ]
    return np.sort(np.concatenate(picks))


def normalised_entropy(p: np.ndarray) -> np.ndarray:
    """Normalised entropy of label distributions (Sec. 7.3, Eq. 7.7).

    ``h = -sum_c p_c log p_c / log |C|``, in [0, 1]: 0 for a one-hot row, 1 for a uniform
    one. (Shannon entropy scaled by its maximum; in R: ``-rowSums(p * log(p)) / log(ncol(p))``.)

    Parameters
    ----------
    p : numpy.ndarray
        (n, c) rows of probabilities summing to 1 (a single (c,) row is accepted).

    Returns
    -------
    numpy.ndarray
        (n,) normalised entropies (a scalar array for a single row).
    """
    p = np.asarray(p, dtype=float)
    single = p.ndim == 1
    p2 = np.atleast_2d(p)
    c = p2.shape[1]
    if c <= 1:
        h = np.zeros(p2.shape[0])
    else:
        terms = np.where(p2 > 0, p2 * np.log(np.where(p2 > 0, p2, 1.0)), 0.0)
        h = np.clip(-terms.sum(axis=1) / np.log(c), 0.0, 1.0)  # Eq. (7.7)
    return h[0] if single else h


def recognise(classifier: SOGPClassifier, Q: np.ndarray) -> tuple[int, int, float, np.ndarray]:
    """Recognise the target and motion cluster over all candidates (5.8, 5.10, Sec. 6.2.3).

    Parameters
    ----------
    classifier : SOGPClassifier
        A fitted classifier.
    Q : numpy.ndarray
        (m, d) query features, one per candidate semantic component, in the classifier's
        input representation.

    Returns
    -------
    best_candidate : int
        Row of ``Q`` with the largest finite posterior mean over all clusters (5.8); -1
        when no score is finite (no recognition).
    best_cluster : int
        The winning cluster id (an element of ``classifier.classes_``); -1 when none.
    beta : float
        The winner's confidence ``Phi(mu / sigma)`` (5.10), the arbitration factor; 0
        when there is no recognition.
    scores : numpy.ndarray
        (m, c) posterior means of every candidate and cluster (columns follow
        ``classifier.classes_``).
    """
    Q = np.atleast_2d(np.asarray(Q, dtype=float))
    if Q.shape[0] < 1:
        raise ValueError("Q: need at least one candidate")
    scores = classifier.scores(Q)
    i, j = argmax_finite(scores)  # Eq. (5.8) over clusters and candidates
    if i < 0:
        return -1, -1, 0.0, scores
    # Only the winner's variance is needed (one O(b^2) product instead of m * c).
    mean, var = classifier.models_[j].predict(Q[i])
    beta = float(ndtr(mean[0] / np.sqrt(var[0])))  # Eq. (5.10)
    if not np.isfinite(beta):
        beta = 0.0
    return i, int(classifier.classes_[j]), beta, scores


def argmax_finite(scores: np.ndarray) -> tuple[int, int]:
    """Row and column of the largest finite entry of ``scores`` (m, c); (-1, -1) if none
    (the first in row-major order on ties; compiled for 2-D arrays, issue 25)."""
    scores = np.asarray(scores, dtype=float)
    if scores.ndim == 2:
        i, j = _tick_kernels.argmax_finite(np.ascontiguousarray(scores))
        return int(i), int(j)
    finite = np.isfinite(scores)
    if not finite.any():
        return -1, -1
    flat = int(np.argmax(np.where(finite, scores, -np.inf)))
    i, j = divmod(flat, scores.shape[1])
    return i, j
