"""Recursive Bayesian filter over contextual tasks with per-task GMR user models (thesis
Ch. 4: Sec. 4.2-4.6, Eqs. 4.4-4.15; spec section 5).

The state is ``x = (task type i, candidate target j)``. Every tick the belief is predicted
with the state transition model (4.13-4.14: stay with probability ``sigma`` = 0.95, else
move uniformly to one of the other states) and corrected with the user model (4.10),
``p_user(u | x) = GMR_i(psi, theta | d)``, a Gaussian mixture regression of the two angles
given the distance, learnt per task type from demonstrations; the number of components is
chosen by the BIC (4.11-4.12) among 1..10. The decision is the MAP state (4.15); its belief
is the confidence (``beta`` of Sec. 4.6).

Chapter-4 features of one candidate, from its robot-frame target point ``s`` [m] and the
command ``u``: ``d = |s|`` [m], ``psi = atan2(s_y, s_x)`` (the angle between the robot's
heading and the target) and ``theta = wrap(atan2(u_y, u_x) - psi)`` (the angle between the
translational input and the target), both in (-pi, pi] [rad] (thesis footnote 2 of Ch. 4:
the target point is the doorway/dock centre or the nearest surface point, as in the
recorded demonstrations). Choices where the thesis is silent: docs/decisions.md.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from sklearn.mixture import GaussianMixture

_LOG_2PI = float(np.log(2.0 * np.pi))

Candidate = tuple[str, str, np.ndarray]  # (component id, component kind, target point (2,) [m])


def target_features(s: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Chapter-4 task features ``(d, psi, theta)`` of target points under one or many inputs.

    Parameters
    ----------
    s : numpy.ndarray
        (m, 2) or (2,) target points in the robot frame [m].
    u : numpy.ndarray
        (m, >=2) or (>=2,) commands; only the direction of ``(u_x, u_y)`` is used, so any
        units do. A single command is broadcast over all target points.

    Returns
    -------
    numpy.ndarray
        (m, 3) ``d`` [m], ``psi`` [rad] in (-pi, pi], ``theta`` [rad] in (-pi, pi].
    """
    S = np.atleast_2d(np.asarray(s, dtype=float))
    U = np.atleast_2d(np.asarray(u, dtype=float))
    if S.shape[1] != 2 or U.shape[1] < 2:
        raise ValueError(
            f"target_features: s must be (m, 2) and u (m, >=2), got {S.shape}, {U.shape}"
        )
    d = np.hypot(S[:, 0], S[:, 1])
    psi = np.arctan2(S[:, 1], S[:, 0])
    theta = _wrap(np.arctan2(U[:, 1], U[:, 0]) - psi)
    return np.column_stack([d, psi, theta])


def _wrap(a: np.ndarray) -> np.ndarray:
    """Wrap to (-pi, pi] [rad]."""
    w = np.arctan2(np.sin(a), np.cos(a))
    return np.where(w <= -np.pi, np.pi, w)


def n_parameters(h: int, dim: int) -> int:
    """Free parameters of an ``h``-component full-covariance GMM in ``dim`` dimensions (4.12)."""
    return (h - 1) + h * (dim + dim * (dim + 1) // 2)  # Eq. (4.12)


class TaskUserModel:
    """User model of one task type: GMR of ``(psi, theta)`` given ``d`` (Eq. 4.10).

    Parameters
    ----------
    max_components : int
        Largest number of GMM components tried by the BIC (10 in the thesis).
    n_init : int
        EM restarts per candidate number of components (best likelihood kept).
    reg_covar : float
        Added to the covariance diagonals [m^2 or rad^2].
    max_iter : int
        EM iterations per restart.

    Attributes
    ----------
    n_components_ : int
        Number of components chosen by the BIC.
    bic_ : numpy.ndarray
        (H,) BIC score (4.11) for h = 1..H.
    weights_, means_, covariances_ : numpy.ndarray
        (h,), (h, 3), (h, 3, 3) the chosen joint GMM over ``(d, psi, theta)``.
    """

    def __init__(
        self,
        *,
        max_components: int = 10,
        n_init: int = 2,
        reg_covar: float = 1e-4,
        max_iter: int = 200,
    ) -> None:
        self.max_components = max_components
        self.n_init = n_init
        self.reg_covar = reg_covar
        self.max_iter = max_iter

    def fit(self, X: np.ndarray, *, rng: np.random.Generator) -> TaskUserModel:
        """Fit GMMs with 1..H components by EM and keep the one with the lowest BIC.

        Parameters
        ----------
        X : numpy.ndarray
            (n, 3) demonstration features ``(d [m], psi [rad], theta [rad])``.
        rng : numpy.random.Generator
            Seeds every EM initialisation.

        Returns
        -------
        TaskUserModel
            self, fitted.
        """
        X = np.asarray(X, dtype=float)
        if X.ndim != 2 or X.shape[1] != 3:
            raise ValueError(
                f"TaskUserModel.fit: X must be (n, 3) = (d, psi, theta), got {X.shape}"
            )
        if not np.all(np.isfinite(X)):
            raise ValueError("TaskUserModel.fit: X must be finite (no NaN or inf)")
        if self.max_components < 1:
            raise ValueError(
                f"TaskUserModel: max_components must be >= 1, got {self.max_components}"
            )
        n, dim = X.shape
        h_max = min(self.max_components, n // (n_parameters(1, dim) + 1))
        if h_max < 1:
            raise ValueError(
                f"TaskUserModel.fit: need at least {n_parameters(1, dim) + 1} points, got {n}"
            )
        scores = []
        best: GaussianMixture | None = None
        best_score = np.inf
        for h in range(1, h_max + 1):
            gmm = GaussianMixture(
                n_components=h,
                covariance_type="full",
                reg_covar=self.reg_covar,
                max_iter=self.max_iter,
                n_init=self.n_init,
                init_params="k-means++",  # seeds only; a full k-means per restart is slow
                random_state=int(rng.integers(2**31 - 1)),
            ).fit(X)
            log_lik = float(gmm.score(X)) * n  # l = sum_j log p(xi_j)
            score = -log_lik + 0.5 * n_parameters(h, dim) * np.log(n)  # Eq. (4.11)
            scores.append(score)
            if score < best_score:
                best, best_score = gmm, score
        assert best is not None  # h_max >= 1, so at least one model was fitted
        self.bic_ = np.asarray(scores)
        self.n_components_ = int(best.n_components)
        self.weights_ = best.weights_.copy()
        self.means_ = best.means_.copy()
        self.covariances_ = best.covariances_.copy()
        self.n_samples_ = n
        self._precompute()
        return self

    def _precompute(self) -> None:
        """Per-component conditioning of ``y = (psi, theta)`` on ``x = d`` (Eq. 4.8)."""
        mu, S = self.means_, self.covariances_
        self._mu_x = mu[:, 0]  # (h,) [m]
        self._var_x = S[:, 0, 0]  # (h,) [m^2]
        self._mu_y = mu[:, 1:]  # (h, 2) [rad]
        self._gain = S[:, 1:, 0] / self._var_x[:, None]  # (h, 2) Sigma_yx Sigma_x^-1
        cond = S[:, 1:, 1:] - np.einsum("ko,kp->kop", self._gain, S[:, 1:, 0])  # Eq. (4.8)
        self._prec_y = np.linalg.inv(cond)  # (h, 2, 2)
        self._logdet_y = np.linalg.slogdet(cond)[1]  # (h,)
        self._log_w = np.log(np.maximum(self.weights_, 1e-300))

    def log_likelihood(self, d: np.ndarray, psi: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """``log GMR_i(psi, theta | d)`` (Eqs. 4.5-4.8, 4.10) for m candidates.

        Parameters
        ----------
        d, psi, theta : numpy.ndarray
            (m,) distance [m] and angles [rad].

        Returns
        -------
        numpy.ndarray
            (m,) log conditional density [log 1/rad^2], finite.
        """
        if not hasattr(self, "weights_"):
            raise RuntimeError("TaskUserModel: call fit() first")
        x = np.atleast_1d(np.asarray(d, dtype=float))
        y = np.column_stack(
            [np.atleast_1d(np.asarray(psi, dtype=float)), np.atleast_1d(np.asarray(theta, float))]
        )
        if y.shape[0] != x.shape[0]:
            raise ValueError("TaskUserModel.log_likelihood: d, psi, theta must have equal length")
        dx = x[None, :] - self._mu_x[:, None]  # (h, m)
        log_px = -0.5 * (dx * dx / self._var_x[:, None] + np.log(self._var_x)[:, None] + _LOG_2PI)
        log_w = self._log_w[:, None] + log_px  # Eq. (4.6)-(4.7)
        log_h = log_w - _logsumexp(log_w, axis=0)  # 1/z of Eq. (4.5)
        mu_c = self._mu_y[:, None, :] + self._gain[:, None, :] * dx[:, :, None]  # Eq. (4.8)
        r = y[None, :, :] - mu_c  # (h, m, 2)
        maha = np.einsum("kmo,kop,kmp->km", r, self._prec_y, r)
        log_n = -0.5 * (maha + self._logdet_y[:, None] + 2.0 * _LOG_2PI)
        return _logsumexp(log_h + log_n, axis=0)[0]  # Eq. (4.5)

    def likelihood(self, d: np.ndarray, psi: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """``p_user(u | x) = GMR_i(psi, theta | d)`` (Eq. 4.10), (m,) [1/rad^2]; see
        :meth:`log_likelihood`."""
        return np.exp(self.log_likelihood(d, psi, theta))


def _logsumexp(a: np.ndarray, axis: int) -> np.ndarray:
    """log(sum(exp(a))) along axis, keeping it."""
    m = a.max(axis=axis, keepdims=True)
    m = np.where(np.isfinite(m), m, 0.0)
    return m + np.log(np.exp(a - m).sum(axis=axis, keepdims=True))


def fit_user_models(
    features: Mapping[str, np.ndarray],
    *,
    rng: np.random.Generator,
    max_components: int = 10,
) -> dict[str, TaskUserModel]:
    """One BIC-selected :class:`TaskUserModel` per task type.

    Parameters
    ----------
    features : mapping of str to numpy.ndarray
        Task type -> (n_i, 3) demonstration features ``(d, psi, theta)`` computed against
        the demonstrated target (:func:`target_features`).
    rng : numpy.random.Generator
        Seeds the EM initialisations.
    max_components : int
        Largest number of components tried.

    Returns
    -------
    dict
        Task type -> fitted model.
    """
    return {
        task: TaskUserModel(max_components=max_components).fit(X, rng=rng)
        for task, X in features.items()
    }


@dataclass(frozen=True, slots=True)
class RecognitionStep:
    """One tick of a recogniser.

    ``belief`` is the filter's posterior over ``states`` (sums to 1), or the baseline's
    per-state confidence ``c`` (each in [0, 1], not a distribution).
    """

    task: str | None  # recognised task type, None for a null decision
    target: str | None  # recognised component id, None for a null decision
    confidence: float  # belief (filter) or c (baseline) of the best state, in [0, 1]
    states: tuple[tuple[str, str], ...]  # (N,) (task type, component id)
    belief: np.ndarray  # (N,) per state
    updated: bool = True  # False if the user model was skipped (no translational input)

    @property
    def decision(self) -> tuple[str, str] | None:
        """``(task, target)``, or None for a null decision."""
        if self.task is None or self.target is None:
            return None
        return (self.task, self.target)


def candidate_states(
    candidates: Sequence[Candidate], kinds: Mapping[str, str]
) -> tuple[list[tuple[str, str]], np.ndarray]:
    """States ``(task type, id)`` for candidates of the kind each task type targets.

    Parameters
    ----------
    candidates : sequence of (id, kind, point)
        Candidate components with their robot-frame target points (2,) [m].
    kinds : mapping of str to str
        Task type -> the component kind it targets.

    Returns
    -------
    states : list of (str, str)
        (N,) in task-type order of ``kinds``, then candidate order.
    points : numpy.ndarray
        (N, 2) the state's target point [m].
    """
    ids = [str(c[0]) for c in candidates]
    if len(set(ids)) != len(ids):
        raise ValueError("candidates: component ids must be unique within one tick")
    states: list[tuple[str, str]] = []
    points: list[np.ndarray] = []
    for task, kind in kinds.items():
        for cid, ckind, point in candidates:
            if ckind == kind:
                states.append((task, str(cid)))
                points.append(np.asarray(point, dtype=float).reshape(2))
    return states, np.array(points, dtype=float).reshape(-1, 2)


class BayesFilterRecogniser:
    """Recursive Bayesian filter over (task type, candidate) (Eqs. 4.4, 4.13-4.15).

    Parameters
    ----------
    models : mapping of str to TaskUserModel
        Task type -> fitted user model (Eq. 4.10).
    kinds : mapping of str to str
        Task type -> component kind it targets (``tasks.contextual.TARGET_KIND``); only
        task types with a model are used.
    stay : float
        Transition coefficient ``sigma`` of Eq. (4.14), in (0, 1]; 0.95 in the thesis.
    null_threshold : float
        MAP belief below this gives a null decision.
    new_prior : float
        Belief a newly appearing state enters with.
    min_speed : float
        Translational input below this (in the units of ``u``) skips the user model.
    """

    def __init__(
        self,
        models: Mapping[str, TaskUserModel],
        kinds: Mapping[str, str],
        *,
        stay: float = 0.95,
        null_threshold: float = 0.5,
        new_prior: float = 0.01,
        min_speed: float = 1e-6,
    ) -> None:
        if not 0.0 < stay <= 1.0:
            raise ValueError(f"BayesFilterRecogniser: stay must lie in (0, 1], got {stay}")
        if not 0.0 <= null_threshold <= 1.0:
            raise ValueError(
                f"BayesFilterRecogniser: null_threshold must lie in [0, 1], got {null_threshold}"
            )
        if not 0.0 < new_prior < 1.0:
            raise ValueError(
                f"BayesFilterRecogniser: new_prior must lie in (0, 1), got {new_prior}"
            )
        missing = [t for t in models if t not in kinds]
        if missing:
            raise ValueError(f"BayesFilterRecogniser: no component kind for task types {missing}")
        self.models = dict(models)
        self.kinds = {t: kinds[t] for t in models}
        self.stay = stay
        self.null_threshold = null_threshold
        self.new_prior = new_prior
        self.min_speed = min_speed
        self.reset()

    def reset(self) -> None:
        """Forget the belief (a new trajectory)."""
        self.belief_: dict[tuple[str, str], float] = {}

    def _prior(self, states: list[tuple[str, str]]) -> np.ndarray:
        """Carried-over belief over the current states, before the transition, (N,)."""
        n = len(states)
        old = np.array([self.belief_.get(x, np.nan) for x in states])
        is_new = np.isnan(old)
        survivors = np.where(is_new, 0.0, old)
        mass_new = self.new_prior * is_new.sum()
        if survivors.sum() <= 0.0 or mass_new >= 1.0:
            return np.full(n, 1.0 / n)
        prior = survivors / survivors.sum() * (1.0 - mass_new)
        prior[is_new] = self.new_prior
        return prior

    def step(self, candidates: Sequence[Candidate], u: np.ndarray) -> RecognitionStep:
        """One filter tick: predict (4.14), correct with the user model (4.10), decide (4.15).

        Parameters
        ----------
        candidates : sequence of (id, kind, point)
            This tick's candidate components and their robot-frame target points (2,) [m].
        u : numpy.ndarray
            (>=2,) the user command; ``(u_x, u_y)`` gives the input direction.

        Returns
        -------
        RecognitionStep
            The MAP decision, its belief and the belief over all states.
        """
        states, points = candidate_states(candidates, self.kinds)
        n = len(states)
        if n == 0:
            self.belief_ = {}
            return RecognitionStep(None, None, 0.0, (), np.zeros(0), updated=False)
        b = self._prior(states)
        if n > 1:  # Eq. (4.14): stay with sigma, else spread uniformly over the other states
            b = self.stay * b + (1.0 - self.stay) * (1.0 - b) / (n - 1)
        u = np.asarray(u, dtype=float).reshape(-1)
        updated = bool(np.hypot(u[0], u[1]) >= self.min_speed)
        if updated:
            feats = target_features(points, u[:2])
            log_lik = np.empty(n)
            tasks = np.array([t for t, _ in states])
            for task, model in self.models.items():
                sel = tasks == task
                if sel.any():
                    f = feats[sel]
                    log_lik[sel] = model.log_likelihood(f[:, 0], f[:, 1], f[:, 2])  # Eq. (4.10)
            with np.errstate(divide="ignore"):
                log_post = np.log(b) + log_lik  # Eq. (4.4), eta by normalising
            b = np.exp(log_post - _logsumexp(log_post, axis=0))
        b = b / b.sum()
        self.belief_ = dict(zip(states, b.tolist(), strict=True))
        best = int(np.argmax(b))  # Eq. (4.15)
        conf = float(b[best])
        task, target = states[best] if conf >= self.null_threshold else (None, None)
        return RecognitionStep(task, target, conf, tuple(states), b, updated=updated)
