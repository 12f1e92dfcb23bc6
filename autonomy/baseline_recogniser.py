"""Exponential-confidence baseline recogniser (thesis Sec. 7.2.1-7.2.2, Eq. 7.5, from the
thesis's reference [24]; spec section 5).

For every candidate state ``(task type, component)`` the confidence is

    c = exp(-k_alpha * alpha * k_beta * beta)                          (7.5)

with ``alpha = d`` the distance to the target point [m] and ``beta = |psi|`` the absolute
angle between the robot's heading and the target [rad], except for wall following where
``beta = ||psi| - 90 deg|`` (Sec. 7.2.2 and its footnote 4: the wall is expected abeam).
The scales are hand-tuned per task type. The recognised state is the one with the highest
``c``; below ``threshold`` the decision is null ("no task identified", the yellow spheres of
Figs. 7.4-7.13). The baseline is reactive: it keeps no memory and ignores the user input.
Choices where the thesis is silent: docs/decisions.md.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from autonomy.bayes_filter import Candidate, RecognitionStep, candidate_states, target_features


@dataclass(frozen=True, slots=True)
class BaselineScales:
    """Hand-tuned scales of Eq. (7.5) for one task type."""

    k_alpha: float = 1.0  # [1/m]
    k_beta: float = 1.0  # [1/rad]
    psi_ref: float = 0.0  # [rad] beta = ||psi| - psi_ref|


@dataclass(frozen=True, slots=True)
class BaselineSettings:
    """Settings of :class:`ExponentialBaseline`; ``scales`` overrides per task type."""

    scales: Mapping[str, BaselineScales] = field(default_factory=dict)
    threshold: float = 0.5  # c below this: null decision
    form: str = "product"  # "product" as Eq. (7.5), or "sum"


def default_scales(kinds: Mapping[str, str]) -> dict[str, BaselineScales]:
    """Default scales per task type: ``psi_ref = pi/2`` for wall kinds, else 0."""
    return {
        task: BaselineScales(psi_ref=np.pi / 2 if kind == "wall" else 0.0)
        for task, kind in kinds.items()
    }


def baseline_confidence(
    d: np.ndarray,
    psi: np.ndarray,
    scales: BaselineScales,
    *,
    form: str = "product",
) -> np.ndarray:
    """Confidence ``c`` of Eq. (7.5).

    Parameters
    ----------
    d : numpy.ndarray
        (m,) distance to the target point, ``alpha`` [m].
    psi : numpy.ndarray
        (m,) angle between heading and target [rad].
    scales : BaselineScales
        ``k_alpha`` [1/m], ``k_beta`` [1/rad], ``psi_ref`` [rad].
    form : str
        ``"product"`` (Eq. 7.5 as printed) or ``"sum"``.

    Returns
    -------
    numpy.ndarray
        (m,) in [0, 1].
    """
    alpha = np.abs(np.asarray(d, dtype=float))
    beta = np.abs(np.abs(np.asarray(psi, dtype=float)) - scales.psi_ref)  # Sec. 7.2.2
    if form == "product":
        return np.exp(-scales.k_alpha * alpha * scales.k_beta * beta)  # Eq. (7.5)
    if form == "sum":
        return np.exp(-scales.k_alpha * alpha - scales.k_beta * beta)
    raise ValueError(f"baseline form must be 'product' or 'sum', got {form!r}")


class ExponentialBaseline:
    """Exponential-confidence baseline with the step() interface of the Bayesian filter.

    Parameters
    ----------
    kinds : mapping of str to str
        Task type -> component kind it targets.
    settings : BaselineSettings or None
        Scales (missing task types get :func:`default_scales`), threshold and form.
    """

    def __init__(self, kinds: Mapping[str, str], *, settings: BaselineSettings | None = None):
        settings = BaselineSettings() if settings is None else settings
        if settings.form not in ("product", "sum"):
            raise ValueError(
                f"ExponentialBaseline: form must be 'product' or 'sum', got {settings.form!r}"
            )
        if not 0.0 <= settings.threshold <= 1.0:
            raise ValueError(
                f"ExponentialBaseline: threshold must lie in [0, 1], got {settings.threshold}"
            )
        unknown = [t for t in settings.scales if t not in kinds]
        if unknown:
            raise ValueError(f"ExponentialBaseline: scales for unknown task types {unknown}")
        self.kinds = dict(kinds)
        self.settings = settings
        self.scales_ = {**default_scales(kinds), **dict(settings.scales)}

    def reset(self) -> None:
        """Nothing to forget: the baseline is reactive."""

    def step(self, candidates: Sequence[Candidate], u: np.ndarray) -> RecognitionStep:
        """Score every candidate state by Eq. (7.5) and pick the best.

        Parameters
        ----------
        candidates : sequence of (id, kind, point)
            This tick's candidate components and their robot-frame target points (2,) [m].
        u : numpy.ndarray
            (>=2,) the user command (unused by Eq. 7.5; kept for the common interface).

        Returns
        -------
        RecognitionStep
            ``belief`` holds ``c`` per state.
        """
        states, points = candidate_states(candidates, self.kinds)
        if not states:
            return RecognitionStep(None, None, 0.0, (), np.zeros(0))
        feats = target_features(points, np.array([1.0, 0.0]))
        c = np.empty(len(states))
        tasks = np.array([t for t, _ in states])
        for task in self.kinds:
            sel = tasks == task
            if sel.any():
                c[sel] = baseline_confidence(
                    feats[sel, 0], feats[sel, 1], self.scales_[task], form=self.settings.form
                )
        best = int(np.argmax(c))
        conf = float(c[best])
        task, target = states[best] if conf >= self.settings.threshold else (None, None)
        return RecognitionStep(task, target, conf, tuple(states), c)
