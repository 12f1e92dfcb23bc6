"""The method of simulated moments on one bank (issue 39): the population parameters that
bring the bank's importance-weighted moments closest to the pilot's, and their bootstrap.

Objective (Gourieroux & Monfort 1996, diagonal weighting)::

    J(theta) = sum_j ((m_j(theta) - t_j) / se_j)^2

over every moment ``j`` of a metric that a fitted block drives (:data:`model.DRIVERS`), with
``t_j`` the pilot's moment, ``se_j`` its bootstrap standard error (moments with se 0 or
undefined are reported, not fitted) and ``m_j(theta)`` the bank's moment under the
importance weights of ``theta`` (:func:`model.block_log_ratios`). Minimised by Nelder-Mead
within each parameter's search bounds. A candidate under which a fitted metric's bank has
fewer than :func:`ess_floor` effective entries (Kish) is outside what the bank can
represent: its moments rest on a handful of entries, so the objective adds a barrier that
grows as the effective size falls below the floor (docs/decisions.md, "asa calibrate").
Every candidate costs array arithmetic on the bank, no simulation. The bootstrap redraws
the pilot's participants *and* the bank's entries, so an interval carries both the pilot's
sampling error and the bank's Monte Carlo error.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from study.jobs.calibrate.model import DRIVERS, Parameter, block_log_ratios
from study.jobs.calibrate.moments import Wide, moments, sample_moments

PENALTY = 1e6  # objective of a candidate whose weighted moments are undefined
ESS_SHARE = 0.25  # the floor of a metric's effective bank size, as a share of the bank
ESS_MIN = 20.0  # ... and at most this many entries (banks over 80)
BARRIER = 100.0  # objective per missing effective entry below the floor


def ess_floor(bank_size: int) -> float:
    """The fewest effective bank entries a candidate's moments may rest on."""
    return min(ESS_MIN, ESS_SHARE * bank_size)


@dataclass(frozen=True, slots=True)
class Problem:
    """Everything a fit needs (sent to the workers for the bootstrap).

    Attributes
    ----------
    params : the fitted parameters, in the order of a parameter vector.
    blocks : the fitted blocks.
    fixed : every key of :func:`model.base_values` (the base population's values).
    pilot : metric -> the pilot's :class:`Wide` (people = its complete participants).
    pilot_people : number of pilot participants (the bootstrap's unit).
    bank : metric -> the bank's :class:`Wide` (people = bank entries).
    bank_values : person-level field -> (B,) the bank entries' values.
    se : metric -> (m,) the pilot moments' standard errors (the weighting).
    """

    params: tuple[Parameter, ...]
    blocks: tuple[str, ...]
    fixed: Mapping[str, float]
    pilot: Mapping[str, Wide]
    pilot_people: int
    bank: Mapping[str, Wide]
    bank_values: Mapping[str, np.ndarray]
    se: Mapping[str, np.ndarray]

    def bank_size(self) -> int:
        return len(next(iter(self.bank_values.values())))

    def fitted_metrics(self) -> tuple[str, ...]:
        return tuple(m for m in self.bank if set(DRIVERS.get(m, ())) & set(self.blocks))

    def theta(self, x: np.ndarray) -> dict[str, float]:
        return {**self.fixed, **{p.name: float(v) for p, v in zip(self.params, x, strict=True)}}


def simulated(problem: Problem, x: np.ndarray, bank_counts: np.ndarray) -> dict:
    """Metric -> the bank's moments under ``x`` (bank entries counted ``bank_counts``), and
    metric -> the effective number of bank entries (Kish: (sum w)^2 / sum w^2)."""
    ratios = block_log_ratios(problem.bank_values, problem.theta(x))
    out, ess = {}, {}
    for metric, w in problem.bank.items():
        drivers = [b for b in DRIVERS.get(metric, ()) if b in ratios]
        logw = sum((ratios[b][w.rows] for b in drivers), np.zeros(len(w.rows)))
        weights = np.exp(logw - logw.max()) * bank_counts[w.rows] if len(w.rows) else logw
        out[metric] = moments(w.values, weights, frequency=False)
        ess[metric] = float(weights.sum() ** 2 / (weights @ weights)) if len(w.rows) else 0.0
    return out, ess


def objective(x, problem: Problem, targets: Mapping, bank_counts: np.ndarray) -> float:
    """J(x) (module docstring)."""
    sims, ess = simulated(problem, x, bank_counts)
    total, floor = 0.0, ess_floor(problem.bank_size())
    for metric in problem.fitted_metrics():
        total += BARRIER * max(0.0, floor - ess[metric])
        se = problem.se[metric]
        use = np.isfinite(targets[metric]) & np.isfinite(se) & (se > 0)
        diff = (sims[metric][use] - targets[metric][use]) / se[use]
        if not np.all(np.isfinite(diff)):
            return PENALTY
        total += float(diff @ diff)
    return total


def fit(problem: Problem, targets: Mapping, bank_counts: np.ndarray, starts) -> np.ndarray:
    """The parameter vector minimising J from the best of ``starts`` (each (p,))."""
    lo = np.array([p.bounds[0] for p in problem.params])
    hi = np.array([p.bounds[1] for p in problem.params])

    def scaled(u):  # the search in [0, 1]^p, so one simplex size suits every parameter
        return objective(lo + u * (hi - lo), problem, targets, bank_counts)

    best = None
    for x0 in starts:
        u0 = np.clip((np.asarray(x0) - lo) / (hi - lo), 0.0, 1.0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            res = minimize(
                scaled, u0, method="Nelder-Mead", bounds=[(0.0, 1.0)] * len(lo),
                options={"xatol": 1e-4, "fatol": 1e-6, "maxiter": 400 * len(lo),
                         "initial_simplex": _simplex(u0)},
            )  # fmt: skip
        if best is None or res.fun < best.fun:
            best = res
    return lo + best.x * (hi - lo)


def _simplex(u0: np.ndarray) -> np.ndarray:
    """A simplex of side 0.15 about ``u0``, inside [0, 1]."""
    p = len(u0)
    out = np.repeat(u0[None, :], p + 1, axis=0)
    for i in range(p):
        out[i + 1, i] += 0.15 if u0[i] <= 0.85 else -0.15
    return out


def pilot_targets(problem: Problem) -> dict[str, np.ndarray]:
    """Metric -> the pilot's moments (every participant once)."""
    return sample_moments(problem.pilot, np.ones(problem.pilot_people))


def bootstrap_fits(problem: Problem, estimate: np.ndarray, seeds: list[int]) -> np.ndarray:
    """(len(seeds), p) fits, each to a bootstrap of the pilot's participants and of the
    bank's entries drawn from its seed (a Dask task: a chunk of replicates)."""
    out = []
    bank_size = problem.bank_size()
    for seed in seeds:
        rng = np.random.default_rng(seed)
        n = problem.pilot_people
        pilot_counts = np.bincount(rng.integers(0, n, n), minlength=n).astype(float)
        bank_counts = np.bincount(rng.integers(0, bank_size, bank_size), minlength=bank_size)
        targets = sample_moments(problem.pilot, pilot_counts)
        out.append(fit(problem, targets, bank_counts.astype(float), [estimate]))
    return np.array(out)
