"""The kind-and-time recogniser (issue 40): which component the driver is working on, and
with which primitive, from the SOGP scores of Ch. 6 (Eqs. 5.6, 5.8) combined with what
the demonstrations say about each kind of component (:mod:`autonomy.intent_prior`) and
filtered over time as the Ch. 4 recogniser does (Eqs. 4.4, 4.14).

Per tick, for candidate ``c`` (kind ``k``, distance ``d`` to its target point) and
primitive ``j``::

    log L(c, j) = a mu_cj + log p(k | j) + w_d [log N(log d; exec_j) - log N(log d; approach)]
    log L(c)    = logsumexp_j log L(c, j) + w_r log p(rank of c) + cues(c)

``mu_cj`` the SOGP posterior mean (5.6); the passage cues are progress along the passage's
axis (``|cos(u, normal)|``) and approach (``cos(u, s_c)``). A null hypothesis (the driver
is on no task) has a constant likelihood. The belief over the candidates and the null
follows the sticky transition of Eq. (4.14), ``stay b + (1 - stay) / N``, and Bayes' rule
(4.4); while the driver idles only the transition runs, so the belief decays towards
uniform and no hypothesis is ever certain. The blend weight is the winner's posterior when
it is decisive (at least ``engage`` and ahead of the runner-up and the null by ``margin``),
else 0. Choices: docs/decisions.md, "The kind-and-time recogniser".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from autonomy.intent_prior import KIND_CLASS, RANKS, IntentPrior

NULL = "\x00null"  # the belief's key of the no-task hypothesis (never a component id)
_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


@dataclass(frozen=True, slots=True)
class KindTimeSettings:
    """Weights and thresholds of the kind-and-time recogniser (docs/decisions.md)."""

    evidence_scale: float = 4.0  # a: weight of the SOGP mean (one-vs-all targets +-1)
    distance_weight: float = 0.5  # w_d: execution against approach distance model
    rank_weight: float = 1.0  # w_r: the target's rank among the nearest
    axis_weight: float = 2.0  # passages: |cos(u, passage normal)|
    toward_weight: float = 1.0  # passages: cos(u, direction to the passage centre)
    stay: float = 0.95  # Eq. (4.14): probability of keeping the hypothesis per tick
    null_log_likelihood: float = 3.0  # log L of the no-task hypothesis
    engage: float = 0.8  # least winner posterior with a non-zero blend weight
    margin: float = 0.5  # least lead over the runner-up and the null
    contradicted: float = 0.5  # belief factor of a hypothesis the driver pushes against

    def __post_init__(self) -> None:
        for name in ("evidence_scale", "distance_weight", "rank_weight", "axis_weight"):
            _check(name, getattr(self, name), 0.0, 100.0)
        _check("toward_weight", self.toward_weight, 0.0, 100.0)
        _check("null_log_likelihood", self.null_log_likelihood, -100.0, 100.0)
        for name in ("stay", "engage", "margin", "contradicted"):
            _check(name, getattr(self, name), 0.0, 1.0)


def _check(name: str, value: object, low: float, high: float) -> None:
    ok = isinstance(value, int | float) and not isinstance(value, bool)
    if not (ok and math.isfinite(value) and low <= value <= high):
        raise ValueError(
            f"contextual_task setting kind_time.{name}: must be a number in [{low:g}, "
            f"{high:g}], got {value!r}"
        )


@dataclass(frozen=True, slots=True)
class Recognition:
    """One tick's decision: the candidate (row of the tick's candidates, -1 for none), its
    primitive (row of the classifier's classes), the blend weight and the belief's
    winner posterior and lead (over the runner-up and the null)."""

    candidate: int
    primitive: int
    beta: float
    posterior: float
    lead: float


class KindTimeRecogniser:
    """Stateful per trial: :meth:`reset` at its start, :meth:`__call__` on every tick with
    input, :meth:`idle` on ticks without.

    Parameters
    ----------
    prior : IntentPrior
        Aligned with the classifier's classes.
    settings : KindTimeSettings
    """

    def __init__(self, prior: IntentPrior, settings: KindTimeSettings) -> None:
        self.prior = prior
        self.settings = settings
        self.belief_: dict[str, float] = {}

    def reset(self) -> None:
        """Forget the belief (a new trial)."""
        self.belief_ = {}

    def idle(self) -> None:
        """A tick without input: the transition (4.14) alone, towards uniform."""
        if self.belief_:
            keys = list(self.belief_)
            b = self._transition(keys)
            self.belief_ = dict(zip(keys, b.tolist(), strict=True))

    def contradict(self, key: str) -> None:
        """The driver pushes against the assistance on ``key``: less belief in it."""
        if key in self.belief_:
            self.belief_[key] *= self.settings.contradicted
            total = sum(self.belief_.values())
            self.belief_ = {k: v / total for k, v in self.belief_.items()}

    def __call__(
        self,
        mean: np.ndarray,
        ids: list[str],
        kinds: list[str],
        targets: np.ndarray,
        normals: np.ndarray,
        u_norm: np.ndarray,
    ) -> Recognition:
        """Decide on one tick.

        Parameters
        ----------
        mean : numpy.ndarray
            (n, J) SOGP posterior means of the candidates (Eq. 5.6), nearest first.
        ids, kinds : list of str
            (n,) the candidates' component ids and kinds.
        targets : numpy.ndarray
            (n, 2) [m] target points, robot frame.
        normals : numpy.ndarray
            (n, 2) passage normals, robot frame (zeros for other kinds).
        u_norm : numpy.ndarray
            (3,) the driver's command in normalised (-1, 1) units.
        """
        n = len(ids)
        if n == 0:
            return Recognition(-1, -1, 0.0, 0.0, 0.0)
        log_l, best_j = self._likelihood(mean, kinds, targets, normals, u_norm)
        keys = [*ids, NULL]
        b = self._transition(keys)
        logs = np.append(log_l, self.settings.null_log_likelihood)
        b = b * np.exp(logs - logs.max())  # Eq. (4.4)
        b /= b.sum()
        self.belief_ = dict(zip(keys, b.tolist(), strict=True))
        i = int(np.argmax(b[:n]))
        rest = np.delete(b, i)
        p1, lead = float(b[i]), float(b[i] - rest.max()) if len(rest) else float(b[i])
        s = self.settings
        beta = p1 if (p1 >= s.engage and lead >= s.margin) else 0.0
        return Recognition(i, int(best_j[i]), beta, p1, lead)

    def _transition(self, keys: list[str]) -> np.ndarray:
        """Eq. (4.14) over ``keys``: the last belief (new hypotheses at 0, renormalised;
        uniform without one) kept with ``stay``, else spread uniformly."""
        old = np.array([self.belief_.get(k, 0.0) for k in keys])
        total = old.sum()
        n = len(keys)
        b = old / total if total > 0 else np.full(n, 1.0 / n)
        return self.settings.stay * b + (1.0 - self.settings.stay) / n

    def _likelihood(
        self,
        mean: np.ndarray,
        kinds: list[str],
        targets: np.ndarray,
        normals: np.ndarray,
        u_norm: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """``log L(c)`` (n,) and each candidate's best primitive (n,) (module docstring)."""
        s, p = self.settings, self.prior
        n = len(kinds)
        k = np.array([KIND_CLASS.get(kind, 0) for kind in kinds])
        d = np.hypot(targets[:, 0], targets[:, 1])
        x = np.log(np.maximum(d, 0.05))[:, None]  # (n, 1)
        z_exec = (x - p.exec_mean[None, :]) / p.exec_sd[None, :]
        z_app = (x - p.approach[0]) / p.approach[1]
        log_exec = -0.5 * z_exec * z_exec - np.log(p.exec_sd)[None, :]
        log_app = -0.5 * z_app * z_app - math.log(p.approach[1])
        lj = s.evidence_scale * np.nan_to_num(mean, nan=-1e3, neginf=-1e3, posinf=1e3)
        lj = lj + p.log_kind[:, k].T + s.distance_weight * (log_exec - log_app)
        best_j = np.argmax(lj, axis=1)
        top = lj.max(axis=1)
        log_l = top + np.log(np.exp(lj - top[:, None]).sum(axis=1))
        log_l += s.rank_weight * p.log_rank[np.minimum(np.arange(n), RANKS - 1)]
        log_l += self._passage_cues(k, d, targets, normals, u_norm)
        return log_l, best_j

    def _passage_cues(
        self, k: np.ndarray, d: np.ndarray, targets: np.ndarray, normals: np.ndarray, u: np.ndarray
    ) -> np.ndarray:
        """(n,) the passages' cues: progress along the axis and approach."""
        s = self.settings
        speed = math.hypot(float(u[0]), float(u[1]))
        out = np.zeros(len(k))
        if speed <= 1e-9:
            return out
        ux, uy = float(u[0]) / speed, float(u[1]) / speed
        norm = np.hypot(normals[:, 0], normals[:, 1])
        axis = np.abs(normals[:, 0] * ux + normals[:, 1] * uy) / np.where(norm > 0, norm, 1.0)
        toward = (targets[:, 0] * ux + targets[:, 1] * uy) / np.where(d > 1e-9, d, 1.0)
        passage = k == 0
        out[passage] = s.axis_weight * axis[passage] + s.toward_weight * toward[passage]
        return out
