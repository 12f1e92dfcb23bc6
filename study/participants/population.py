"""The synthetic participants' population model and their NASA-TLX model (issue 6;
thesis Sec. 7.6): a *model*, not data; its choices are in docs/decisions.md."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from questionnaires import nasa_tlx

DISTRACTIONS: tuple[str, ...] = ("hold", "drift", "release")
TLX_ORDER: tuple[str, ...] = nasa_tlx.SUBSCALE_IDS


# ---------------------------------------------------------------------- parameters


@dataclass(frozen=True, slots=True)
class ParticipantParams:
    """One synthetic person (each field's model: docs/decisions.md)."""

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
    tlx_bias_mean: float = 0.0  # [points] mean of the people's NASA-TLX bias
    tlx_bias_sd: float = 8.0  # [points] its sd between people
    tlx_gain_range: tuple[float, float] = (0.7, 1.3)  # use of the scale's range

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
        g_lo, g_hi = self.tlx_gain_range
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
            tlx_bias=round(float(self.tlx_bias_mean + self.tlx_bias_sd * rng.standard_normal()), 3),
            tlx_gain=round(float(g_lo + (g_hi - g_lo) * u[10]), 4),
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
