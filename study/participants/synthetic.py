"""Synthetic participants: simulated people who drive with a gamepad while doing mental
arithmetic (issue 6; thesis Sec. 7.6). The population they are drawn from and their
NASA-TLX model are in :mod:`study.participants.population`; the driving model's choices
are in docs/decisions.md."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
from numba import njit

from questionnaires import nasa_tlx
from sim.semantics import derive_components, with_semantic_source
from sim.types import Observation, SemanticComponent, wrap_angle
from study.participants.base import ParticipantBase
from study.participants.population import (
    DISTRACTIONS,
    TLX_ORDER,
    ParticipantParams,
    Population,
    TrialLoad,
    tlx_ratings,
)
from study.participants.scripted import (
    ScriptedParticipant,
    ScriptedSettings,
    answer_is_correct,
    uniform_answer,
)
from study.types import ParticipantInput, ScreenState, TrialInfo
from tasks.guard import guard_uvw
from tasks.skills import SkillSettings
from tasks.stick import HumanStick, HumanStickSettings

__all__ = [
    "DISTRACTIONS",
    "TLX_ORDER",
    "ParticipantParams",
    "Population",
    "SyntheticParticipant",
    "TrialLoad",
    "synthetic_participant",
    "tlx_ratings",
]

DT = 0.05  # [s] the control tick the stick model assumes
_ZERO = (0.0, 0.0, 0.0)  # no command (v_x, v_y, omega) [m/s, m/s, rad/s]
_DRIFT_SIGMA = (0.01, 0.01, 0.03)  # [m/s, m/s, rad/s] a distracted hand's drift


# ---------------------------------------------------------------------- the participant


_PHASES = ("training", "practice", "baseline", "main")


def trial_stream(root: int, info: TrialInfo) -> np.random.Generator:
    """A trial's own random stream, from the participant's ``root`` seed and the trial's
    identity (phase, position in it, attempt): what a person does in one trial does not
    depend on how many draws earlier trials took (so a change to one mode's trials leaves
    the others' as they were)."""
    phase = _PHASES.index(info.phase) if info.phase in _PHASES else len(_PHASES)
    attempt = info.attempt_of[0] if info.attempt_of else 1
    return np.random.default_rng([root, phase, info.ordinal, attempt])


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


@njit(cache=True)
def _nearest_run(points: np.ndarray, starts: np.ndarray, px: float, py: float) -> tuple[int, float]:
    """Of the runs of ``points`` (n, 2) [m] starting at ``starts`` (k,), the one with the
    point nearest (px, py) [m] and that point's squared distance [m^2]: numpy's
    ``argmin`` of ``minimum.reduceat`` of ``dx * dx + dy * dy`` (the first on ties, NaN
    propagating as there)."""
    best, best_d2 = 0, math.inf
    for r in range(starts.shape[0]):
        stop = starts[r + 1] if r + 1 < starts.shape[0] else points.shape[0]
        low = math.inf
        for j in range(starts[r], stop):
            dx, dy = points[j, 0] - px, points[j, 1] - py
            d2 = dx * dx + dy * dy
            if j == starts[r] or not (low <= d2 or math.isnan(low)):
                low = d2
        if r == 0 or low < best_d2 or (math.isnan(low) and not math.isnan(best_d2)):
            best, best_d2 = r, low
    return best, best_d2


class SyntheticParticipant(ParticipantBase):
    """A synthetic person behind the participant interface (its model: docs/decisions.md).

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
        self._trial_seed = int(rng.integers(2**62))  # root of every trial's own stream
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
        # where this person's own task labels (the truth recognition is scored against)
        # take their components from: None the scene's semantics; "geometry" the exact
        # shapes, when the assistance reads a map of a scene drawn exactly (issue 23)
        self.label_semantics: str | None = None
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
        self._last_u = _ZERO  # commands as (v_x, v_y, omega) [m/s, m/s, rad/s] floats
        self._drift = _ZERO
        self._ticks = 0
        self._mismatch = 0.0
        self._mismatch_n = 0
        self._prev_pose: tuple[float, float, float] | None = None  # [m, m, rad]
        self._prev_u = _ZERO
        self._stuck_anchor: tuple[float, float, float] | None = None  # t [s], x, y [m]
        self._unstick_until = -math.inf
        self._unstick_u = _ZERO
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
        self._rng = trial_stream(self._trial_seed, info)
        self._driver.reseed(np.random.default_rng(int(self._rng.integers(2**62))))
        self._stick.reset(np.random.default_rng(int(self._rng.integers(2**62))))
        self._driver.begin_trial(info)
        self._passages = []
        self._expected_s = math.nan
        if not info.drive:
            return
        length = 0.0
        scenario = info.scenario
        if self.label_semantics is not None:
            scenario = with_semantic_source(scenario, self.label_semantics)
        key = f"{scenario.source or scenario.name} {scenario.semantics.source}"
        if key not in self._components:
            self._components[key] = derive_components(scenario)
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
        dock = info.scenario.dock
        docks = [c for c in comps if c.kind == "dock"]
        for c in comps:
            if c.kind == "object" and name and name in c.source:
                self._inspect_id = c.id
        if dock is not None and docks:  # the dock at pose B (a scene may have several)
            b = np.array([dock.pose.x, dock.pose.y])
            self._dock_id = min(docks, key=lambda c: float(np.hypot(*(c.centre - b)))).id
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
            self._drift = _ZERO
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
        i, d2 = _nearest_run(points, starts, px, py)
        dist, comp = math.sqrt(d2), comps[i]
        if comp.kind == "wall" and dist < 0.9 and math.isfinite(tangents[i]):
            # the direction of travel (map frame) from the last stick command
            u0, u1, _ = self._prev_u
            heading = pose.yaw + (math.atan2(u1, u0) if u0 != 0 or u1 != 0 else 0.0)
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
        px, py = float(pose.x), float(pose.y)
        if self._prev_pose is not None:
            self._note_mismatch(px, py, pose.yaw)
        self._prev_pose = (px, py, float(pose.yaw))
        u0, u1, u2 = self._driver.command(obs, False)  # the ideal command, no question
        self._task = self._label(obs)
        if self._task[0] in ("doorway_crossing", "gap_crossing", "robot_docking"):
            slower = 1.0 - 0.4 * self.params.caution
            u0, u1 = u0 * slower, u1 * slower
        u0, u1, u2 = guard_uvw(u0, u1, u2, obs.points, self._guard)
        u0, u1, u2 = self._unstick(t, px, py, (u0, u1, u2))
        if self._question is not None and self._answered != self._question and self._d > 0:
            x0, x1, x2 = self._distracted_command()
            d, e = self._d, 1.0 - self._d
            u0, u1, u2 = e * u0 + d * x0, e * u1 + d * x1, e * u2 + d * x2
        else:
            self._last_u = (u0, u1, u2)
        self._prev_u = self._stick.filter_uvw(u0, u1, u2)
        return ParticipantInput(u=np.array(self._prev_u), answer=answer)

    def _note_mismatch(self, px: float, py: float, yaw: float) -> None:
        """Count how far the robot's motion since the last tick (robot frame, per tick)
        was from the last command, relative to it, when it asked for translation."""
        w0, w1, _ = self._prev_u
        if w0 == 0 and w1 == 0:
            return
        m0, m1 = px - self._prev_pose[0], py - self._prev_pose[1]
        c, s = math.cos(yaw), math.sin(yaw)
        g0, g1 = (c * m0 + s * m1) / DT - w0, (-s * m0 + c * m1) / DT - w1
        norm = math.sqrt(w0 * w0 + w1 * w1)
        self._mismatch += float(min(1.0, math.sqrt(g0 * g0 + g1 * g1) / max(norm, 0.05)))
        self._mismatch_n += 1

    def _distracted_command(self) -> tuple[float, float, float]:
        style = self.params.distraction
        if style == "release":
            return _ZERO
        a0, a1, a2 = self._last_u
        self._last_u = (a0 * 0.97, a1 * 0.97, a2 * 0.97)  # eased off over a few seconds
        if style == "drift":
            # rng.normal(0.0, sigma) as numpy computes it (loc + scale * a standard
            # normal draw, the same draws) without its broadcasting overhead
            z0, z1, z2 = self._rng.standard_normal(3).tolist()
            s0, s1, s2 = _DRIFT_SIGMA
            d0, d1, d2 = self._drift
            self._drift = (
                0.95 * d0 + (0.0 + s0 * z0),
                0.95 * d1 + (0.0 + s1 * z1),
                0.95 * d2 + (0.0 + s2 * z2),
            )
            a0, a1, a2 = self._last_u
            d0, d1, d2 = self._drift
            return (a0 + d0, a1 + d1, a2 + d2)
        return self._last_u

    def _unstick(
        self, t: float, px: float, py: float, ideal: tuple[float, float, float]
    ) -> tuple[float, float, float]:
        if t < self._unstick_until:
            return self._unstick_u
        u0, u1, u2 = ideal
        pushing = math.sqrt(u0 * u0 + u1 * u1) > 0.05 or abs(u2) > 0.1
        if not pushing or self._stuck_anchor is None:
            self._stuck_anchor = (t, px, py)
            return ideal
        t0, x0, y0 = self._stuck_anchor
        if math.sqrt((px - x0) * (px - x0) + (py - y0) * (py - y0)) > 0.05:
            self._stuck_anchor = (t, px, py)
            return ideal
        if t - t0 >= 2.0:
            turn = 1.0 if self._rng.random() < 0.5 else -1.0
            self._unstick_u = (-0.15, 0.1 * turn, 0.5 * turn)
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
