"""Synthetic participants: a sampled population of simulated people who drive with a
gamepad while doing mental arithmetic (issue 6; thesis Sec. 7.6, spec section 7).

This is a *model*, not data. Every number below is a documented choice; where the thesis
gives a figure it is cited, elsewhere the range is what an HRI researcher would call
plausible for students and staff driving a simulated robot with a gamepad.

The population (:class:`Population`, sampled with a passed-in generator)
-----------------------------------------------------------------------
- ``preferred_speed`` [m/s]: how fast a person likes to drive; log-normal about 0.3 m/s,
  clipped to [0.2, 0.45] (thesis Sec. 7.2.3, 7.3, 7.4: "the average speed of the robot
  ... was approximately 0.3 m/s").
- ``steering_noise``: multiplier of the stick tremor of :class:`tasks.skills.HumanStick`
  (1 = its default); lower for people familiar with gamepads (``gamepad`` item).
- ``overshoot_rate_hz``: onsets of over-/undershoot episodes; grows with the noise.
- ``reaction_delay_s`` [s]: stick reaction delay, uniform in [0.15, 0.35] (simple
  visuo-motor reaction times), applied as whole 50 ms ticks.
- ``caution`` in [0, 1]: the margin kept from obstacles (the skills' guard margin and
  stopping distance) and how much a person slows down in narrow places.
- ``question_disturbance`` in [0, 1]: how much an open question takes attention from
  driving; ``distraction`` is how the hand behaves meanwhile: ``"hold"`` (the last
  command is held and slowly eased off), ``"drift"`` (held, with a growing uncorrected
  drift) or ``"release"`` (the stick is let go). The driving input while a question is
  open is ``(1 - d) * attended + d * distracted`` with ``d`` = disturbance times a
  per-question draw in [0.5, 1].
- Arithmetic: ``answer_time_s`` (median, seated, no driving; log-normal in about
  [1.4, 3.2] s for the verification of a two-digit sum), ``error_rate`` (no driving;
  [0.02, 0.10]); while driving answers are ``dual_task_slowdown`` times slower ([1.1, 1.6])
  and errors ``dual_task_error_factor`` times likelier ([1.0, 2.5]): the thesis found
  answer times with driving significantly longer than the baseline (Sec. 7.6.2,
  Fig. 7.51). Each answer time is log-normal about that median (sigma 0.25).
- Questionnaire style: ``tlx_bias`` (points added to every rating, N(0, 8)),
  ``tlx_gain`` (use of the range, [0.7, 1.3]), ``tlx_noise`` (sd of rating noise,
  [3, 8] points) and ``tlx_importance`` (Dirichlet(2) over the six subscales: which
  sources of workload the person considers important; drives the pairwise choices).
- The experience questionnaire: ``age`` (18-45), ``handedness`` (about 10 % left),
  ``driving``, ``games``, ``gamepad``, ``robots`` on the 1..5 scales; ``gamepad`` is
  drawn from ``games`` and lowers the steering noise.

Driving (decisions where the spec is silent)
--------------------------------------------
- The route is planned as the scripted driver plans it (:mod:`study.participants.scripted`:
  shortest paths on the occupancy grid through the trial's goals, A -> dock at B -> A,
  and, when asked, an inspection orbit around the object moving sideways while facing it;
  the participant is given the complete map, thesis Sec. 7.6.1.1). The ideal command of
  its pure-pursuit follower, on the *estimated* pose of every tick's observation (closed
  loop: what the assistance does to the robot feeds back into the next command), is
  taken at the participant's preferred speed, slowed in narrow places by caution, and
  kept off the laser points by the skills' guard (:func:`tasks.skills.guard_command`);
  it then passes :class:`tasks.skills.HumanStick` (delay, tremor, over-/undershoot,
  deadzone, quantisation).
- Contextual tasks (the ground truth, :meth:`SyntheticParticipant.intention`): the
  route is split by what the robot is doing where it is: docking within 1.5 m of B on
  the way to B; inspection on the orbit and over the last 1.5 m of the way to it;
  doorway or gap crossing within 1 m of a passage the planned path goes through; wall
  following when a wall is within 0.9 m beside the robot and the direction of travel is
  within 30 degrees of the wall; object bypass within 0.6 m of an object; otherwise free
  driving, logged as ``("", "")``.
- Stuck: when the robot has not moved 5 cm in 2 s although the person pushes the stick,
  the person tries something else for 1-1.5 s (backs off and turns a random way, as
  people wiggle out of a jam), then resumes.
- Questions are read as they appear; the answer is pressed after the drawn answer time
  (a time beyond the task's timeout lets the question time out).

Training: the model does not learn (its skill is fixed by the sampled parameters), so
``learns = False`` and the session engine skips the protocol's training phase, recording
why (:mod:`study.engine.session`); everything from practice on is run as for a person.

Questionnaires: :func:`tlx_ratings` turns what the trial was like (:class:`TrialLoad`,
from the stored outcome and what the participant noticed while driving) into ratings;
see its docstring. Pairwise choices prefer the subscale with the larger importance
(probability ``w_a^2 / (w_a^2 + w_b^2)``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from questionnaires import nasa_tlx
from sim.semantics import derive_components
from sim.types import Observation, SemanticComponent, wrap_angle
from study.participants.base import ParticipantBase
from study.participants.scripted import (
    ScriptedParticipant,
    ScriptedSettings,
    answer_is_correct,
    fast_norm,
    uniform_answer,
)
from study.types import ParticipantInput, ScreenState, TrialInfo
from tasks.skills import HumanStick, HumanStickSettings, SkillSettings, guard_command

DT = 0.05  # [s] the control tick the stick model assumes
DISTRACTIONS: tuple[str, ...] = ("hold", "drift", "release")
TLX_ORDER: tuple[str, ...] = nasa_tlx.SUBSCALE_IDS


# ---------------------------------------------------------------------- parameters


@dataclass(frozen=True, slots=True)
class ParticipantParams:
    """One synthetic person (see the module docstring for each field's model)."""

    preferred_speed: float  # [m/s]
    steering_noise: float  # multiplier of HumanStick's tremor sigma
    overshoot_rate_hz: float  # [1/s]
    reaction_delay_s: float  # [s]
    caution: float  # [0, 1]
    question_disturbance: float  # [0, 1]
    distraction: str  # DISTRACTIONS
    answer_time_s: float  # [s] median, no driving
    error_rate: float  # probability of a wrong answer, no driving
    dual_task_slowdown: float  # answer-time factor while driving (>= 1)
    dual_task_error_factor: float  # error-rate factor while driving (>= 1)
    tlx_bias: float  # [points]
    tlx_gain: float  # use of the scale's range
    tlx_noise: float  # [points] sd
    tlx_importance: tuple[float, ...]  # (6,) in TLX_ORDER, sums to 1
    age: int  # [years]
    handedness: str  # "right", "left", "ambidextrous"
    driving: int  # 1..5
    games: int  # 1..5
    gamepad: int  # 1..5
    robots: int  # 1..5

    def as_dict(self) -> dict[str, Any]:
        """JSON-able parameters (stored with the participant row)."""
        out = asdict(self)
        out["tlx_importance"] = list(self.tlx_importance)
        return out

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> ParticipantParams:
        """The inverse of :meth:`as_dict` (other keys, e.g. a study's bookkeeping, are
        ignored; a missing field is an error)."""
        fields = {k: v for k, v in values.items() if k in cls.__dataclass_fields__}
        fields["tlx_importance"] = tuple(float(w) for w in fields.get("tlx_importance", ()))
        return cls(**fields)


@dataclass(frozen=True, slots=True)
class Population:
    """Ranges of the population model (change with ``dataclasses.replace``)."""

    speed_median: float = 0.3  # [m/s] thesis Sec. 7.2.3: about 0.3 m/s
    speed_sigma: float = 0.15  # log-normal sigma
    speed_range: tuple[float, float] = (0.2, 0.45)  # [m/s]
    noise_range: tuple[float, float] = (0.6, 1.6)  # steering-noise multiplier
    delay_range_s: tuple[float, float] = (0.15, 0.35)  # [s]
    disturbance_range: tuple[float, float] = (0.2, 0.8)
    distraction_p: tuple[float, float, float] = (0.4, 0.35, 0.25)  # hold, drift, release
    answer_time_median_s: float = 2.1  # [s]
    answer_time_sigma: float = 0.2  # log-normal sigma between people
    error_range: tuple[float, float] = (0.02, 0.10)
    slowdown_range: tuple[float, float] = (1.1, 1.6)
    error_factor_range: tuple[float, float] = (1.0, 2.5)
    age_range: tuple[int, int] = (18, 45)  # [years]

    def sample(self, rng: np.random.Generator) -> ParticipantParams:
        """One person.

        Parameters
        ----------
        rng : numpy.random.Generator
            The only source of randomness; the same state gives the same person.
        """
        u = rng.random(16)
        games = 1 + int(u[0] * 5)
        gamepad = int(np.clip(games + rng.integers(-1, 2), 1, 5))
        skill = (gamepad - 1) / 4.0  # 0..1
        lo, hi = self.noise_range
        noise = hi - (hi - lo) * (0.6 * skill + 0.4 * u[1])
        speed = float(
            np.clip(
                self.speed_median * math.exp(self.speed_sigma * rng.standard_normal()),
                *self.speed_range,
            )
        )
        d_lo, d_hi = self.disturbance_range
        e_lo, e_hi = self.error_range
        s_lo, s_hi = self.slowdown_range
        f_lo, f_hi = self.error_factor_range
        style = DISTRACTIONS[int(np.searchsorted(np.cumsum(self.distraction_p), u[2] * 0.99999))]
        answer = self.answer_time_median_s * math.exp(
            self.answer_time_sigma * rng.standard_normal()
        )
        importance = rng.dirichlet(np.full(len(TLX_ORDER), 2.0))
        handed = "left" if u[3] < 0.1 else ("ambidextrous" if u[3] < 0.13 else "right")
        a_lo, a_hi = self.age_range
        return ParticipantParams(
            preferred_speed=round(speed, 4),
            steering_noise=round(float(noise), 4),
            overshoot_rate_hz=round(0.1 + 0.2 * float(noise), 4),
            reaction_delay_s=round(
                float(self.delay_range_s[0] + u[4] * np.ptp(self.delay_range_s)), 4
            ),
            caution=round(float(u[5]), 4),
            question_disturbance=round(float(d_lo + (d_hi - d_lo) * u[6]), 4),
            distraction=style,
            answer_time_s=round(float(np.clip(answer, 1.4, 3.2)), 4),
            error_rate=round(float(e_lo + (e_hi - e_lo) * u[7]), 4),
            dual_task_slowdown=round(float(s_lo + (s_hi - s_lo) * u[8]), 4),
            dual_task_error_factor=round(float(f_lo + (f_hi - f_lo) * u[9]), 4),
            tlx_bias=round(float(8.0 * rng.standard_normal()), 3),
            tlx_gain=round(float(0.7 + 0.6 * u[10]), 4),
            tlx_noise=round(float(3.0 + 5.0 * u[11]), 4),
            tlx_importance=tuple(round(float(w), 5) for w in importance),
            age=int(a_lo + int(u[12] * (a_hi - a_lo + 1))),
            handedness=handed,
            driving=1 + int(u[13] * 5),
            games=games,
            gamepad=gamepad,
            robots=int(np.clip(1 + int(u[14] * 3) + (1 if u[15] < skill * 0.3 else 0), 1, 5)),
        )

    def sample_many(self, n: int, rng: np.random.Generator) -> list[ParticipantParams]:
        """``n`` people from one generator, in order."""
        return [self.sample(rng) for _ in range(int(n))]


# ---------------------------------------------------------------------- NASA-TLX model


@dataclass(frozen=True, slots=True)
class TrialLoad:
    """What a trial was like for the participant (inputs of :func:`tlx_ratings`)."""

    time_ratio: float  # completion time / the time the person expected (>= 0)
    collisions: int  # collision episodes
    completed: bool  # the route was finished
    corrections: float  # [0, 1] how much the robot did not do what the stick said
    question_load: float  # [0, 1] questions per minute of the trial, scaled (20/min = 1)
    answer_errors: float  # [0, 1] share of wrong or timed-out answers


def _latent(load: TrialLoad) -> np.ndarray:
    """Latent workload per subscale [points, about 0..100] in TLX_ORDER."""
    late = float(np.clip(load.time_ratio - 1.0, 0.0, 2.0))
    hits = float(min(load.collisions, 5))
    fail = 0.0 if load.completed else 1.0
    q, c, e = load.question_load, load.corrections, load.answer_errors
    return np.array(
        [
            25.0 + 35.0 * q + 10.0 * c + 3.0 * hits + 10.0 * e,  # mental
            15.0 + 20.0 * c + 8.0 * late + 2.0 * hits,  # physical
            20.0 + 25.0 * late + 20.0 * q + 10.0 * fail,  # temporal
            10.0 + 10.0 * hits + 15.0 * late + 25.0 * e + 35.0 * fail,  # performance (failure)
            25.0 + 20.0 * q + 15.0 * c + 4.0 * hits + 10.0 * late,  # effort
            10.0 + 9.0 * hits + 20.0 * c + 10.0 * late + 10.0 * e + 30.0 * fail,  # frustration
        ]
    )


def tlx_ratings(load: TrialLoad, params: ParticipantParams, z: np.ndarray) -> dict[str, int]:
    """The six NASA-TLX ratings of one trial (a model, not data).

    ``rating = clip(round5(50 + gain * (latent - 50) + bias + noise * z), 0, 100)`` per
    subscale, where ``latent`` rises with time pressure (``time_ratio`` above 1),
    collisions, corrections, question load, answer errors and a failed route (each
    subscale with the sources its definition names, e.g. collisions on performance and
    frustration, questions on mental and temporal demand).

    Parameters
    ----------
    load : TrialLoad
        What the trial was like.
    params : ParticipantParams
        The person's answering style (``tlx_gain``, ``tlx_bias``, ``tlx_noise``).
    z : numpy.ndarray
        (6,) standard normal draws (the rating noise), in :data:`TLX_ORDER`.

    Returns
    -------
    dict[str, int]
        Subscale id -> rating in 0..100, a multiple of 5.
    """
    raw = (
        50.0
        + params.tlx_gain * (_latent(load) - 50.0)
        + params.tlx_bias
        + params.tlx_noise * np.asarray(z, dtype=float)
    )
    stepped = np.clip(np.round(raw / 5.0) * 5.0, 0.0, 100.0)
    return {k: int(v) for k, v in zip(TLX_ORDER, stepped, strict=True)}


# ---------------------------------------------------------------------- the participant


def _segments_cross(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> bool:
    """Whether the polyline ``p`` (k, 2) crosses the segment ``a``-``b``."""
    if len(p) < 2:
        return False
    p0, p1 = p[:-1], p[1:]
    d = p1 - p0
    e = b - a

    def cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
        return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]

    den = cross(d, e)
    ok = np.abs(den) > 1e-12
    with np.errstate(divide="ignore", invalid="ignore"):
        t = cross(a - p0, e) / den
        s = cross(a - p0, d) / den
    return bool(np.any(ok & (t >= 0) & (t <= 1) & (s >= 0) & (s <= 1)))


# walls and objects (map frame) for the per-tick "what is beside me" test: the components,
# their surface points stacked (n, 2) [m], each one's first row, each wall's tangent [rad]
_Nearby = tuple[list[SemanticComponent], np.ndarray, np.ndarray, np.ndarray]


def _nearby(components: Sequence[SemanticComponent]) -> _Nearby | None:
    near = [c for c in components if c.kind in ("wall", "object") and len(c.points)]
    if not near:
        return None
    tangents = np.full(len(near), math.nan)
    for k, c in enumerate(near):
        if c.kind == "wall" and len(c.points) > 2:
            centred = c.points - c.points.mean(axis=0)
            _, vecs = np.linalg.eigh(centred.T @ centred)
            tangents[k] = math.atan2(vecs[1, -1], vecs[0, -1])
    starts = np.cumsum([0] + [len(c.points) for c in near[:-1]])
    return near, np.vstack([c.points for c in near]), starts, tangents


class SyntheticParticipant(ParticipantBase):
    """A synthetic person behind the participant interface (see the module docstring).

    Parameters
    ----------
    params : ParticipantParams
        Who the person is (:meth:`Population.sample`).
    rng : numpy.random.Generator
        The only source of randomness of everything the person does.
    """

    kind = "synthetic"
    # the model's skill is a fixed sample: the session engine skips the training phase
    learns = False

    def __init__(self, params: ParticipantParams, rng: np.random.Generator) -> None:
        self.params = params
        self.parameters: dict[str, Any] = params.as_dict()
        self._rng = rng
        self._driver = ScriptedParticipant(
            np.random.default_rng(int(rng.integers(2**62))),
            settings=replace(
                ScriptedSettings(),
                speed=params.preferred_speed,
                orbit_speed=min(params.preferred_speed, 0.3),
            ),
        )
        self._guard = replace(
            SkillSettings(),
            guard_margin=0.05 * params.caution,
            guard_stop=0.01 + 0.08 * params.caution,
        )
        self._stick = HumanStick(
            HumanStickSettings(
                preferred_speed=1.0,
                reference_speed=1.0,
                noise_sigma=tuple(s * params.steering_noise for s in (0.04, 0.04, 0.08)),
                delay_ticks=max(0, round(params.reaction_delay_s / DT)),
                overshoot_rate_hz=params.overshoot_rate_hz,
            )
        )
        self.texts_read: list[str] = []
        self._info: TrialInfo | None = None
        self._outcome: dict[str, Any] | None = None
        self._task: tuple[str, str] = ("", "")
        self._passages: list[tuple[str, str, float, float]] = []  # kind, id, centre [m]
        self._expected_s = math.nan
        self._components: dict[str, tuple[SemanticComponent, ...]] = {}
        self._nearby: dict[str, _Nearby | None] = {}
        self._near: _Nearby | None = None
        self._inspect_id = ""
        self._dock_id = ""
        self._reset_trial_state()

    def _reset_trial_state(self) -> None:
        self._question: str | None = None
        self._answer_at = math.inf
        self._answer_right = True
        self._answered: str | None = None
        self._d = 0.0
        self._last_u = np.zeros(3)
        self._drift = np.zeros(3)
        self._ticks = 0
        self._mismatch = 0.0
        self._mismatch_n = 0
        self._prev_pose: np.ndarray | None = None
        self._prev_u = np.zeros(3)
        self._stuck_anchor: tuple[float, np.ndarray] | None = None
        self._unstick_until = -math.inf
        self._unstick_u = np.zeros(3)
        self._distracted = 0
        self._task = ("", "")

    # ------------------------------------------------------------------ reading, forms

    def read(self, text: str) -> None:
        """Acknowledge a text at once (kept in ``texts_read``)."""
        self.texts_read.append(text)

    def fill(self, instrument: Any, *, context: Mapping[str, Any]) -> dict[str, Any]:
        """Answer the experience questionnaire from the parameters, NASA-TLX from the last
        trial (:func:`tlx_ratings`); any other instrument uniformly at random."""
        p = self.params
        if instrument.id == nasa_tlx.INSTRUMENT_ID:
            return dict(tlx_ratings(self.trial_load(), p, self._rng.standard_normal(6)))
        answers: dict[str, Any] = {}
        known = {
            "age": p.age,
            "handedness": p.handedness,
            "driving": p.driving,
            "games": p.games,
            "gamepad": p.gamepad,
            "robots": p.robots,
        }
        for item in instrument.items:
            if instrument.id == "experience" and item.id in known:
                answers[item.id] = known[item.id]
            else:
                answers[item.id] = uniform_answer(item, self._rng)
        return answers

    def choose(self, pairs: Sequence[tuple[str, str]]) -> dict[tuple[str, str], str]:
        """Each pair: the subscale with the larger importance, with probability
        ``w_a^2 / (w_a^2 + w_b^2)``."""
        w = dict(zip(TLX_ORDER, self.params.tlx_importance, strict=True))
        out: dict[tuple[str, str], str] = {}
        for a, b in pairs:
            wa, wb = w.get(a, 1.0) ** 2, w.get(b, 1.0) ** 2
            p_a = wa / (wa + wb) if wa + wb > 0 else 0.5
            out[(a, b)] = a if self._rng.random() < p_a else b
        return out

    # ------------------------------------------------------------------ trials

    def begin_trial(self, info: TrialInfo) -> None:
        """Plan the route and the contextual tasks along it; reset the hand."""
        self._info = info
        self._outcome = None
        self._reset_trial_state()
        self._stick.reset(np.random.default_rng(int(self._rng.integers(2**62))))
        self._driver.begin_trial(info)
        self._passages = []
        self._expected_s = math.nan
        if not info.drive:
            return
        length = 0.0
        key = info.scenario.source or info.scenario.name
        if key not in self._components:
            self._components[key] = derive_components(info.scenario)
        comps = self._components[key]
        legs = self._driver._legs  # the planned route (same package, read-only)
        polylines = [leg.points for leg in legs if hasattr(leg, "points")]
        for leg in legs:
            if hasattr(leg, "points"):
                length += float(np.sum(np.linalg.norm(np.diff(leg.points, axis=0), axis=1)))
            else:
                length += leg.radius * leg.arc
        for c in comps:
            if c.kind in ("doorway", "gap") and len(c.ends) == 2:
                if any(_segments_cross(p, c.ends[0], c.ends[1]) for p in polylines):
                    kind = "doorway_crossing" if c.kind == "doorway" else "gap_crossing"
                    cx, cy = (float(v) for v in c.centre)
                    self._passages.append((kind, c.id, cx, cy))
        self._inspect_id = ""
        self._dock_id = ""
        name = info.scenario.inspection_object
        for c in comps:
            if c.kind == "object" and name and name in c.source:
                self._inspect_id = c.id
            if c.kind == "dock":
                self._dock_id = c.id
        self._expected_s = length / max(self.params.preferred_speed, 1e-3)
        if key not in self._nearby:
            self._nearby[key] = _nearby(comps)
        self._near = self._nearby[key]

    def end_trial(self, outcome: dict[str, Any]) -> None:
        """Remember how the trial went (rated by the next NASA-TLX)."""
        self._outcome = dict(outcome)

    def trial_load(self) -> TrialLoad:
        """What the last trial was like, from its stored outcome and what was noticed."""
        out = self._outcome or {}
        duration = float(out.get("completion_time_s") or out.get("duration_s") or 0.0)
        expected = self._expected_s if math.isfinite(self._expected_s) else max(duration, 1.0)
        sec = out.get("secondary") or {}
        shown = int(sec.get("shown") or 0)
        errors = int(sec.get("errors") or 0)
        minutes = max(float(out.get("duration_s") or duration or 1.0) / 60.0, 1e-3)
        corrections = self._mismatch / self._mismatch_n if self._mismatch_n else 0.0
        return TrialLoad(
            time_ratio=duration / max(expected, 1e-3),
            collisions=int(out.get("collisions") or 0),
            completed=bool(out.get("completed", True)),
            corrections=float(np.clip(corrections, 0.0, 1.0)),
            question_load=float(np.clip(shown / minutes / 20.0, 0.0, 1.0)),
            answer_errors=float(errors / shown) if shown else 0.0,
        )

    # ------------------------------------------------------------------ acting

    def intention(self) -> tuple[str, str]:
        """The contextual task being performed now: (task type, component id) or
        ``("", "")`` while driving freely."""
        return self._task

    def _answer(self, screen: ScreenState, t: float) -> bool | None:
        text = screen.question
        if text is None:
            self._question = None
            return None
        if text != self._question:  # a new question (a blank gap separates equal ones)
            p = self.params
            driving = self._info is not None and self._info.drive
            median = p.answer_time_s * (p.dual_task_slowdown if driving else 1.0)
            err = min(0.5, p.error_rate * (p.dual_task_error_factor if driving else 1.0))
            z, e, k = self._rng.standard_normal(), self._rng.random(), self._rng.random()
            self._question, self._answered = text, None
            self._answer_at = t + median * math.exp(0.25 * z)
            self._answer_right = bool(e >= err)
            self._d = p.question_disturbance * (0.5 + 0.5 * k) if driving else 0.0
            self._drift = np.zeros(3)
            self._distracted += 1
        if self._answered == text or t < self._answer_at:
            return None
        self._answered = text
        right = answer_is_correct(text)
        return right if self._answer_right else not right

    def _label(self, obs: Observation) -> tuple[str, str]:
        info = self._info
        if info is None or not info.drive:
            return ("", "")
        driver = self._driver
        legs = driver._legs
        if driver._leg >= len(legs):
            return ("", "")
        leg = legs[driver._leg]
        pose = obs.pose
        px, py = float(pose.x), float(pose.y)
        if not hasattr(leg, "points"):
            return ("object_inspection", self._inspect_id)
        # distances as plain floats (numpy on 2-vectors costs more than the numbers)
        ex, ey = float(leg.points[-1][0]) - px, float(leg.points[-1][1]) - py
        to_end = math.sqrt(ex * ex + ey * ey)
        if leg.face is not None and to_end < 1.5:
            return ("object_inspection", self._inspect_id)
        if leg.final_yaw is not None and self._dock_id and to_end < 1.5:
            return ("robot_docking", self._dock_id)
        for kind, cid, cx, cy in self._passages:
            dx, dy = cx - px, cy - py
            if math.sqrt(dx * dx + dy * dy) < 1.0:
                return (kind, cid)
        near = self._near
        if near is None:
            return ("", "")
        comps, points, starts, tangents = near
        off = points - np.array((px, py))
        d2 = np.einsum("ij,ij->i", off, off)
        per = np.minimum.reduceat(d2, starts)
        i = int(np.argmin(per))
        dist, comp = math.sqrt(float(per[i])), comps[i]
        if comp.kind == "wall" and dist < 0.9 and math.isfinite(tangents[i]):
            # the direction of travel (map frame) from the last stick command
            u = self._prev_u
            heading = pose.yaw + (math.atan2(u[1], u[0]) if np.any(u[:2]) else 0.0)
            rel = abs(wrap_angle(heading - tangents[i]))
            if min(rel, math.pi - rel) < math.radians(30):
                return ("wall_following", comp.id)
        if comp.kind == "object" and dist < 0.6 and comp.id != self._inspect_id:
            return ("object_bypass", comp.id)
        return ("", "")

    def act(self, obs: Observation, screen: ScreenState) -> ParticipantInput:
        """One tick: answer, drive (attended or distracted), through the hand's stick."""
        t = obs.t
        answer = self._answer(screen, t)
        info = self._info
        if info is None or not info.drive or screen.paused:
            return ParticipantInput(u=np.zeros(3), answer=answer)
        self._ticks += 1
        pose = obs.pose
        pos = np.array([pose.x, pose.y])
        # what the robot did with the last command (robot frame, per tick)
        prev_u = self._prev_u
        if self._prev_pose is not None and (prev_u[0] != 0 or prev_u[1] != 0):
            moved = pos - self._prev_pose[:2]
            c, s = math.cos(pose.yaw), math.sin(pose.yaw)
            got = np.array([c * moved[0] + s * moved[1], -s * moved[0] + c * moved[1]]) / DT
            want = self._prev_u[:2]
            norm = fast_norm(want)
            self._mismatch += float(min(1.0, fast_norm(got - want) / max(norm, 0.05)))
            self._mismatch_n += 1
        self._prev_pose = np.array([pose.x, pose.y, pose.yaw])
        ideal = self._driver.act(obs, replace(screen, question=None)).u
        ideal = np.asarray(ideal, dtype=float)
        self._task = self._label(obs)
        if self._task[0] in ("doorway_crossing", "gap_crossing", "robot_docking"):
            ideal = ideal * np.array([1.0 - 0.4 * self.params.caution] * 2 + [1.0])
        ideal = guard_command(ideal, obs.points, self._guard)
        ideal = self._unstick(t, pos, ideal)
        if self._question is not None and self._answered != self._question and self._d > 0:
            distracted = self._distracted_command()
            ideal = (1.0 - self._d) * ideal + self._d * distracted
        else:
            self._last_u = ideal
        u = self._stick.filter(ideal)
        self._prev_u = u
        return ParticipantInput(u=u, answer=answer)

    def _distracted_command(self) -> np.ndarray:
        style = self.params.distraction
        if style == "release":
            return np.zeros(3)
        self._last_u = self._last_u * 0.97  # eased off over a few seconds
        if style == "drift":
            self._drift = 0.95 * self._drift + self._rng.normal(0.0, [0.01, 0.01, 0.03])
            return self._last_u + self._drift
        return self._last_u

    def _unstick(self, t: float, pos: np.ndarray, ideal: np.ndarray) -> np.ndarray:
        if t < self._unstick_until:
            return self._unstick_u
        pushing = fast_norm(ideal[:2]) > 0.05 or abs(float(ideal[2])) > 0.1
        if not pushing or self._stuck_anchor is None:
            self._stuck_anchor = (t, pos)
            return ideal
        t0, p0 = self._stuck_anchor
        if fast_norm(pos - p0) > 0.05:
            self._stuck_anchor = (t, pos)
            return ideal
        if t - t0 >= 2.0:
            turn = 1.0 if self._rng.random() < 0.5 else -1.0
            self._unstick_u = np.array([-0.15, 0.1 * turn, 0.5 * turn])
            self._unstick_until = t + 1.0 + 0.5 * self._rng.random()
            self._stuck_anchor = None
            return self._unstick_u
        return ideal


def synthetic_participant(
    rng: np.random.Generator, *, population: Population | None = None
) -> SyntheticParticipant:
    """A new person drawn from ``population`` (default ``Population()``) with ``rng``,
    which then drives their behaviour."""
    population = population if population is not None else Population()
    params = population.sample(rng)
    return SyntheticParticipant(params, rng)
