"""The kind-and-time recogniser (issue 40): which component the driver is working on, and
with which primitive, from the SOGP scores of Ch. 6 (Eqs. 5.6, 5.8) combined with what
the demonstrations say about each kind of component (:mod:`autonomy.intent_prior`) and
filtered over time as the Ch. 4 recogniser does (Eqs. 4.4, 4.14).

Per tick, for candidate ``c`` (kind ``k``, distance ``d`` to its target point) and
primitive ``j``::

    log L(c, j) = a mu_cj + log p(k | j) + w_d [log N(log d; exec_j) - log N(log d; approach)]
    log L(c)    = logsumexp_j log L(c, j) + w_r log p(rank of c) + cues(c)

``mu_cj`` the SOGP posterior mean (5.6); the passage cues are progress along the passage's
axis (``|cos(u, normal)|``) and approach (``cos(u, s_c)``; leaving a doorway or gap within
``exit_radius`` of its centre counts as its mirror image approaching it: the crossing goes
on), and a dock moved away from loses ``dock_departure`` (a goal, never crossed). A null
hypothesis (the driver is on no task) has a constant likelihood. The belief over the
candidates and the null follows the sticky transition of Eq. (4.14), ``stay b + (1 - stay)
/ N``, and Bayes' rule (4.4); while the driver idles only the transition runs, so the
belief decays towards uniform and no hypothesis is ever certain. The blend weight is the
winner's posterior when it is decisive (at least ``engage`` and ahead of the runner-up and
the null by ``margin``), else 0. Choices: docs/decisions.md, "The kind-and-time
recogniser".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from autonomy import _intent_kernels
from autonomy.intent_prior import KIND_CLASS, IntentPrior

NULL = "\x00null"  # the belief's key of the no-task hypothesis (never a component id)


@dataclass(frozen=True, slots=True)
class KindTimeSettings:
    """Weights and thresholds of the kind-and-time recogniser (docs/decisions.md)."""

    evidence_scale: float = 4.0  # a: weight of the SOGP mean (one-vs-all targets +-1)
    distance_weight: float = 0.5  # w_d: execution against approach distance model
    rank_weight: float = 1.0  # w_r: the target's rank among the nearest
    axis_weight: float = 2.0  # passages: |cos(u, passage normal)|
    toward_weight: float = 2.0  # passages: cos(u, direction to the passage centre)
    # a dock is a goal, approached and never crossed (Sec. 4.2.4): log L of moving away
    dock_departure: float = 5.0
    # [m] a crossing goes on past the centre: within this of it, moving away along the
    # passage's axis while on it counts as progress (|cos(s_c, normal)| |cos(u, normal)|)
    exit_radius: float = 1.0
    stay: float = 0.95  # Eq. (4.14): probability of keeping the hypothesis per tick
    null_log_likelihood: float = 2.75  # log L of the no-task hypothesis
    engage: float = 0.8  # least winner posterior with a non-zero blend weight
    margin: float = 0.5  # least lead over the runner-up and the null
    contradicted: float = 0.5  # belief factor of a hypothesis the driver pushes against

    def __post_init__(self) -> None:
        for name in ("evidence_scale", "distance_weight", "rank_weight", "axis_weight"):
            _check(name, getattr(self, name), 0.0, 100.0)
        _check("toward_weight", self.toward_weight, 0.0, 100.0)
        _check("dock_departure", self.dock_departure, 0.0, 100.0)
        _check("exit_radius", self.exit_radius, 0.0, 10.0)
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
        s = settings
        # the kernel's floats (autonomy._intent_kernels.likelihood), then the rank prior
        self.params_ = np.concatenate(
            (
                [s.evidence_scale, s.distance_weight, *prior.approach, s.rank_weight],
                [s.axis_weight, s.toward_weight, s.dock_departure, s.exit_radius],
                prior.log_rank,
            )
        ).astype(float)

    def reset(self) -> None:
        """Forget the belief (a new trial)."""
        self.belief_ = {}

    def idle(self) -> None:
        """A tick without input: the transition (4.14) alone, towards uniform."""
        if self.belief_:
            keys = list(self.belief_)
            self.belief_ = dict(zip(keys, self._transition(keys), strict=True))

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
        prior = self._transition(keys)
        logs = [*log_l.tolist(), self.settings.null_log_likelihood]
        top = max(logs)
        b = [p * math.exp(x - top) for p, x in zip(prior, logs, strict=True)]  # Eq. (4.4)
        total = sum(b)
        b = [v / total for v in b]
        self.belief_ = dict(zip(keys, b, strict=True))
        i = max(range(n), key=b.__getitem__)  # the first of equals, as argmax
        p1 = b[i]
        lead = p1 - max(v for k, v in enumerate(b) if k != i)
        s = self.settings
        beta = p1 if (p1 >= s.engage and lead >= s.margin) else 0.0
        return Recognition(i, int(best_j[i]), beta, p1, lead)

    def _transition(self, keys: list[str]) -> list[float]:
        """Eq. (4.14) over ``keys``: the last belief (new hypotheses at 0, renormalised;
        uniform without one) kept with ``stay``, else spread uniformly (plain floats: a
        handful of hypotheses)."""
        old = [self.belief_.get(k, 0.0) for k in keys]
        total = sum(old)
        n = len(keys)
        stay = self.settings.stay
        if total <= 0:
            return [1.0 / n] * n
        return [stay * v / total + (1.0 - stay) / n for v in old]

    def _likelihood(
        self,
        mean: np.ndarray,
        kinds: list[str],
        targets: np.ndarray,
        normals: np.ndarray,
        u_norm: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """``log L(c)`` (n,) and each candidate's best primitive (n,) (module docstring),
        computed by :func:`autonomy._intent_kernels.likelihood`."""
        n = len(kinds)
        kind = np.array([KIND_CLASS.get(k, 0) for k in kinds], dtype=np.int64)
        dock = np.array([k == "dock" for k in kinds], dtype=np.bool_)
        log_l, best = np.empty(n), np.empty(n, dtype=np.int64)
        p = self.prior
        _intent_kernels.likelihood(
            np.ascontiguousarray(mean, dtype=float),
            kind,
            dock,
            np.ascontiguousarray(targets, dtype=float),
            np.ascontiguousarray(normals, dtype=float),
            np.ascontiguousarray(u_norm, dtype=float),
            p.log_kind,
            p.exec_mean,
            p.exec_sd,
            self.params_,
            log_l,
            best,
        )
        return log_l, best
