"""What ``asa calibrate`` fits (issue 39): the population parameters, the planned metrics
that identify them, the bank's proposal of person-level values and the importance weights
that turn the bank into any candidate population (docs/decisions.md, "asa calibrate").

A fitted parameter belongs to a *block* of person-level values
(:class:`study.participants.population.ParticipantParams` fields):

- ``speed``: ``preferred_speed`` ~ log-normal(``speed_median``, ``speed_sigma``) clipped to
  :data:`SPEED_CLIP` (completion time and score: their level and their spread between
  people);
- ``answer``: ``answer_time_s`` ~ log-normal(``answer_time_median_s``, the base population's
  ``answer_time_sigma``) clipped to :data:`ANSWER_CLIP` (the secondary task's baseline level)
  and ``dual_task_slowdown`` ~ uniform of the base width about ``slowdown_mid`` (the
  secondary task's answer time while driving over the baseline);
- ``tlx``: ``tlx_bias`` ~ normal(``tlx_bias_mean``, ``tlx_bias_sd``) (the NASA-TLX level and
  the people's spread, which is what makes a person's ratings correlate across modes).

The bank draws each fitted block from a wide proposal ``q`` (:class:`Proposal`) and every
other value from the base population. A candidate population ``p`` weighs bank entry ``i``
by ``w_i = prod_b p_b(x_ib) / q_b(x_ib)`` over the blocks ``b`` that drive the metric
(:data:`DRIVERS`); clipped values are point masses in both ``p`` and ``q``, so the ratio is
exact there too.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.stats import norm

from study.participants.population import ParticipantParams, Population

SPEED_CLIP = (0.12, 0.6)  # [m/s] the calibrated population's speed_range
ANSWER_CLIP = (1.4, 3.2)  # [s] Population.sample's clip of answer_time_s
SLOWDOWN_SUPPORT = (1.0, 2.6)  # proposal of dual_task_slowdown
TLX_PROPOSAL_SD = 20.0  # [points] proposal of tlx_bias: normal(0, this)
EDGE_P = 0.05  # proposal's mass at each clip bound
SMOOTH = 0.02  # sd of the normal smoothing the uniform slowdown's edges (weights only)


@dataclass(frozen=True, slots=True)
class Parameter:
    """One fitted population parameter."""

    name: str  # Population field, or "slowdown_mid" (centre of slowdown_range)
    block: str  # "speed", "answer" or "tlx"
    bounds: tuple[float, float]  # search range, inside the proposal's support
    unit: str
    meaning: str


PARAMETERS: tuple[Parameter, ...] = (
    Parameter("speed_median", "speed", (0.15, 0.5), "m/s", "median preferred speed"),
    Parameter("speed_sigma", "speed", (0.04, 0.5), "", "log-normal sigma of preferred speed"),
    Parameter("answer_time_median_s", "answer", (1.5, 3.0), "s", "median answer time"),
    Parameter("slowdown_mid", "answer", (1.05, 2.3), "", "mean dual-task slowdown"),
    Parameter("tlx_bias_mean", "tlx", (-25.0, 25.0), "points", "mean NASA-TLX bias"),
    Parameter("tlx_bias_sd", "tlx", (1.0, 25.0), "points", "NASA-TLX bias sd between people"),
)
BY_PARAMETER = {p.name: p for p in PARAMETERS}
BLOCKS = ("speed", "answer", "tlx")

# metric -> the block it identifies (a block is fitted when one of its metrics is planned)
IDENTIFIES: dict[str, str] = {
    "completion_time_s": "speed",
    "score_s": "speed",
    "secondary_answer_time_s": "answer",
    "tlx_raw": "tlx",
    "tlx_weighted": "tlx",
}
# metric -> every block whose values move it (the weights of its moments); a metric not
# listed is moved by no fitted block: its moments are reported, not fitted
DRIVERS: dict[str, tuple[str, ...]] = {
    "completion_time_s": ("speed",),
    "score_s": ("speed",),
    "collisions": ("speed",),
    "path_length_m": ("speed",),
    "secondary_answer_time_s": ("answer",),
    "tlx_raw": ("speed", "tlx"),
    "tlx_weighted": ("speed", "tlx"),
    **{
        f"tlx_{s}": ("speed", "tlx")
        for s in ("mental", "physical", "temporal", "performance", "effort", "frustration")
    },  # fmt: skip
}


def active_blocks(levels: Mapping[str, tuple[str, ...]]) -> tuple[str, ...]:
    """The blocks the pilot identifies, from its metrics' levels (metric -> levels); the
    answer block needs the secondary task's baseline level (else the answer time and the
    slowdown cannot be told apart)."""
    found = set()
    for metric, lv in levels.items():
        block = IDENTIFIES.get(metric)
        if block == "answer" and "baseline" not in lv:
            continue
        if block is not None:
            found.add(block)
    return tuple(b for b in BLOCKS if b in found)


def fitted_parameters(blocks: tuple[str, ...]) -> tuple[Parameter, ...]:
    return tuple(p for p in PARAMETERS if p.block in blocks)


def start_values(base: Population, params: tuple[Parameter, ...]) -> np.ndarray:
    """The base population's values of ``params``, inside their search bounds."""
    values = base_values(base)
    return np.array([float(np.clip(values[p.name], *p.bounds)) for p in params])


def base_values(base: Population) -> dict[str, float]:
    """Every fitted parameter's value in ``base`` (and the fixed ones the weights need)."""
    lo, hi = base.slowdown_range
    return {
        "speed_median": base.speed_median,
        "speed_sigma": base.speed_sigma,
        "answer_time_median_s": base.answer_time_median_s,
        "answer_time_sigma": base.answer_time_sigma,
        "slowdown_mid": (lo + hi) / 2.0,
        "slowdown_width": hi - lo,
        "tlx_bias_mean": base.tlx_bias_mean,
        "tlx_bias_sd": base.tlx_bias_sd,
    }


def population_with(base: Population, blocks: tuple[str, ...], values: Mapping) -> Population:
    """``base`` with the fitted values (the speed clip becomes :data:`SPEED_CLIP`, as in the
    bank's weights)."""
    v = {**base_values(base), **values}
    changes: dict = {}
    if "speed" in blocks:
        changes.update(speed_median=v["speed_median"], speed_sigma=v["speed_sigma"])
        changes["speed_range"] = SPEED_CLIP
    if "answer" in blocks:
        half = v["slowdown_width"] / 2.0
        changes["answer_time_median_s"] = v["answer_time_median_s"]
        changes["slowdown_range"] = (v["slowdown_mid"] - half, v["slowdown_mid"] + half)
    if "tlx" in blocks:
        changes.update(tlx_bias_mean=v["tlx_bias_mean"], tlx_bias_sd=v["tlx_bias_sd"])
    return dataclasses.replace(base, **changes)


# --------------------------------------------------------------------------- proposal


@dataclass(frozen=True, slots=True)
class Proposal:
    """The bank's draw of the fitted blocks' person-level values (sent to the workers)."""

    blocks: tuple[str, ...]

    def draw(self, person: ParticipantParams, rng: np.random.Generator) -> ParticipantParams:
        """``person`` (drawn from the base population) with the fitted blocks redrawn."""
        changes: dict = {}
        if "speed" in self.blocks:
            changes["preferred_speed"] = round(_clipped_log_uniform(rng, SPEED_CLIP), 4)
        if "answer" in self.blocks:
            changes["answer_time_s"] = round(_clipped_log_uniform(rng, ANSWER_CLIP), 4)
            changes["dual_task_slowdown"] = round(float(rng.uniform(*SLOWDOWN_SUPPORT)), 4)
        if "tlx" in self.blocks:
            changes["tlx_bias"] = round(float(TLX_PROPOSAL_SD * rng.standard_normal()), 3)
        return dataclasses.replace(person, **changes)


def _clipped_log_uniform(rng: np.random.Generator, clip: tuple[float, float]) -> float:
    """A clip bound with probability EDGE_P each, else log-uniform between them."""
    u = rng.random()
    if u < EDGE_P:
        return clip[0]
    if u < 2 * EDGE_P:
        return clip[1]
    return float(math.exp(rng.uniform(math.log(clip[0]), math.log(clip[1]))))


# --------------------------------------------------------------------------- weights


def _clipped_lognormal_ratio(x, median, sigma, clip) -> np.ndarray:
    """log p(x) / q(x): p log-normal(median, sigma) clipped to ``clip``, q the proposal."""
    lo, hi = clip
    at_lo, at_hi = np.isclose(x, lo, atol=1e-6), np.isclose(x, hi, atol=1e-6)
    z = (np.log(np.clip(x, 1e-9, None)) - math.log(median)) / sigma
    # interior: the 1/x of both densities cancels
    out = norm.logpdf(z) - math.log(sigma) - math.log((1 - 2 * EDGE_P) / math.log(hi / lo))
    out = np.where(at_lo, norm.logcdf((math.log(lo) - math.log(median)) / sigma), out)
    out = np.where(at_hi, norm.logsf((math.log(hi) - math.log(median)) / sigma), out)
    return np.where(at_lo | at_hi, out - math.log(EDGE_P), out)


def block_log_ratios(values: Mapping[str, np.ndarray], theta: Mapping[str, float]) -> dict:
    """Block -> (B,) log importance ratio of the bank's entries under ``theta``.

    Parameters
    ----------
    values : person-level field -> (B,) the bank entries' values.
    theta : every key of :func:`base_values` (the fitted ones at their candidate values).
    """
    out = {}
    if "preferred_speed" in values:
        out["speed"] = _clipped_lognormal_ratio(
            values["preferred_speed"], theta["speed_median"], theta["speed_sigma"], SPEED_CLIP
        )
    if "answer_time_s" in values:
        answer = _clipped_lognormal_ratio(
            values["answer_time_s"], theta["answer_time_median_s"], theta["answer_time_sigma"],
            ANSWER_CLIP,
        )  # fmt: skip
        x, half = values["dual_task_slowdown"], theta["slowdown_width"] / 2.0
        lo, hi = theta["slowdown_mid"] - half, theta["slowdown_mid"] + half
        inside = norm.cdf((x - lo) / SMOOTH) - norm.cdf((x - hi) / SMOOTH)
        slow = np.log(np.clip(inside, 1e-300, None) / (hi - lo) * np.ptp(SLOWDOWN_SUPPORT))
        out["answer"] = answer + slow
    if "tlx_bias" in values:
        x = values["tlx_bias"]
        mean, sd = theta["tlx_bias_mean"], theta["tlx_bias_sd"]
        out["tlx"] = norm.logpdf(x, mean, sd) - norm.logpdf(x, 0.0, TLX_PROPOSAL_SD)
    return out


BLOCK_FIELDS = {
    "speed": ("preferred_speed",),
    "answer": ("answer_time_s", "dual_task_slowdown"),
    "tlx": ("tlx_bias",),
}
