"""Power from a pilot: the model of the study's analysis fitted to a pilot's participants,
and studies simulated from it (parametric bootstrap; issue 39).

Per planned metric the pilot's complete participants give a wide matrix ``Y`` (n, k), one
row per participant and one column per level. Two models of it:

- ``"mvn"``, the model of the repeated-measures ANOVA: ``y_i ~ N(mu, Sigma)`` with the mode
  means ``mu`` (k,) and the participants' covariance across modes ``Sigma`` (k, k),
  unstructured (sample mean and covariance, ddof 1). Sphericity is not assumed.
- ``"lmm"``, the linear mixed model with a random intercept per participant:
  ``y_ij = mu_j + b_i + e_ij``, ``b_i ~ N(0, s_b^2)``, ``e_ij ~ N(0, s_e^2)``, i.e.
  ``Sigma = s_b^2 J + s_e^2 I`` (compound symmetry). On complete balanced data REML gives
  ``s_e^2 = MS_error`` and ``s_b^2 = max(0, (MS_subject - MS_error) / k)`` (Searle, Casella &
  McCulloch 1992, ch. 4); in R ``lmer(y ~ mode + (1 | participant))``.

A simulated study of N draws N rows from the fitted model; it is analysed by
:meth:`analysis.power.resample.PlannedTests.analyse`, the same chain ``asa power`` and the
report use. Three variants of the parameters (:data:`VARIANTS`):

- ``"pilot"``: the pilot's estimates (simr's ``powerSim`` on the fitted model);
- ``"uncertain"``: for each study the estimates of a bootstrap replicate of the pilot
  (participants drawn with replacement), replicate ``s mod B`` for study ``s``: the share
  of rejections is the power expected over the pilot's uncertainty (assurance; O'Hagan,
  Stevens & Campbell 2005), and the spread of the replicates' powers is reported;
- ``"interest"``: the pilot's means shrunk (or stretched) about their grand mean so that
  the largest difference between two levels is the smallest effect size of interest
  (simr's ``fixef<-``), the covariance the pilot's.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from analysis.power.resample import Batch, PlannedTests, analyse_study

MODELS: tuple[str, ...] = ("mvn", "lmm")
VARIANTS: tuple[str, ...] = ("pilot", "uncertain", "interest")
MIN_PILOT = 3  # complete participants: a covariance across modes needs at least 3
_CODES = {v: i for i, v in enumerate(VARIANTS)}


@dataclass(frozen=True, slots=True)
class PilotModel:
    """One metric's fitted model of the pilot.

    Attributes
    ----------
    metric : the metric's name.
    levels : (k,) level names in report order.
    wide : (n, k) the pilot's complete participants' values, the data the model is fitted to.
    kind : :data:`MODELS`.
    interest : the smallest effect size of interest (largest level difference, the metric's
        units), or None.
    """

    metric: str
    levels: tuple[str, ...]
    wide: np.ndarray  # (n, k) [metric units]
    kind: str = "mvn"
    interest: float | None = None

    def fit(self) -> tuple[np.ndarray, np.ndarray]:
        """(mean (k,), covariance (k, k)) of the pilot."""
        return fit_moments(self.wide, self.kind)


def fit_moments(wide: np.ndarray, kind: str = "mvn") -> tuple[np.ndarray, np.ndarray]:
    """The mode means and the covariance across modes of ``wide`` (n, k) under ``kind``.

    In R (``"mvn"``): ``colMeans(Y); cov(Y)``.
    """
    y = np.asarray(wide, dtype=float)
    n, k = y.shape
    mean = y.mean(axis=0)
    if kind == "mvn":
        return mean, np.atleast_2d(np.cov(y, rowvar=False, ddof=1))
    if kind != "lmm":
        raise ValueError(f"model {kind!r} is not allowed; choose one of {', '.join(MODELS)}")
    grand = y.mean()
    subject = y.mean(axis=1, keepdims=True)
    resid = y - subject - mean + grand  # the two-way additive model's residuals
    ms_error = float(np.sum(resid**2)) / ((n - 1) * (k - 1))
    ms_subject = k * float(np.sum((subject - grand) ** 2)) / (n - 1)
    var_b = max(0.0, (ms_subject - ms_error) / k)  # REML, balanced data, truncated at 0
    return mean, var_b * np.ones((k, k)) + ms_error * np.eye(k)


def at_effect(mean: np.ndarray, effect: float) -> np.ndarray:
    """``mean`` (k,) scaled about its average so that ``max - min`` is ``effect``.

    Raises ValueError when the levels' means are all equal (nothing to scale).
    """
    mean = np.asarray(mean, dtype=float)
    spread = float(np.ptp(mean))
    if spread <= 1e-12 * max(1.0, float(np.max(np.abs(mean)))):
        raise ValueError("the pilot's level means are all equal: no effect to scale")
    centre = mean.mean()
    return centre + (mean - centre) * (float(effect) / spread)


def replicate(wide: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A bootstrap replicate of the pilot: its n rows drawn with replacement."""
    rows = rng.integers(0, wide.shape[0], size=wide.shape[0])
    return wide[rows]


def _psd(cov: np.ndarray) -> np.ndarray:
    """``cov`` with negative eigenvalues (rounding) set to 0, for sampling."""
    w, v = np.linalg.eigh((cov + cov.T) / 2.0)
    return (v * np.clip(w, 0.0, None)) @ v.T


def study_frame(
    mean: np.ndarray, cov: np.ndarray, n: int, levels: Sequence[str], rng: np.random.Generator
) -> pd.DataFrame:
    """A simulated study of ``n`` participants as the long frame ``analyse`` takes
    (``participant``, ``mode``, ``value``): rows ``y_i ~ N(mean, cov)``."""
    y = rng.multivariate_normal(mean, _psd(cov), size=n, method="eigh")
    k = len(levels)
    return pd.DataFrame(
        {
            "participant": np.repeat([f"S{i:04d}" for i in range(n)], k),
            "mode": np.tile(np.asarray(levels, dtype=object), n),
            "value": y.ravel(),
        }
    )


def parameters(
    model: PilotModel, variant: str, study: int, *, seed: int, draws: int, index: int
) -> tuple[np.ndarray, np.ndarray]:
    """The (mean, covariance) a study of ``variant`` is simulated from (see the module)."""
    if variant == "uncertain":
        rng = np.random.default_rng([int(seed), 39, index, study % draws])
        return fit_moments(replicate(model.wide, rng), model.kind)
    mean, cov = model.fit()
    if variant == "interest":
        mean = at_effect(mean, float(model.interest))
    return mean, cov


def simulate_batch(
    models: Mapping[str, PilotModel],
    planned: PlannedTests,
    batch: Batch,
    *,
    seed: int,
    draws: int,
) -> dict[str, dict[str, np.ndarray]]:
    """Simulate and analyse the studies of ``batch`` for every entry of ``planned.metrics``.

    ``planned.metrics`` is keyed by :func:`variant_key` names (``metric`` for the pilot's
    estimates, ``metric@uncertain``, ``metric@interest``); ``models`` by metric. Study ``s``
    of size N of variant v and metric number i draws from ``default_rng([seed, N, s, i,
    code(v)])``, so batches and workers do not change a decision.

    Returns
    -------
    dict
        As :func:`analysis.power.resample.resample_batch`: key -> test -> (count,) bool.
    """
    count = batch.stop - batch.start
    names = list(models)
    out = {
        key: {t: np.zeros(count, dtype=bool) for t in (*planned.keys(key), "_failed")}
        for key in planned.metrics
    }
    for key in planned.metrics:
        metric, variant = split_key(key)
        model, index = models[metric], names.index(metric)
        for i, study in enumerate(range(batch.start, batch.stop)):
            mean, cov = parameters(model, variant, study, seed=seed, draws=draws, index=index)
            rng = np.random.default_rng([int(seed), batch.n, study, index, _CODES[variant]])
            frame = study_frame(mean, cov, batch.n, model.levels, rng)
            got = analyse_study(frame, planned, key)
            if got is None:
                out[key]["_failed"][i] = True
                continue
            for test, rejected in got.items():
                out[key][test][i] = rejected
    return out


def variant_key(metric: str, variant: str) -> str:
    """The name of a metric's variant in the result (``metric`` for ``"pilot"``)."""
    return metric if variant == "pilot" else f"{metric}@{variant}"


def split_key(key: str) -> tuple[str, str]:
    """The inverse of :func:`variant_key`."""
    metric, _, variant = key.partition("@")
    return metric, variant or "pilot"


def replicate_powers(
    batches: Sequence[tuple[int, int, dict]], key: str, test: str, draws: int
) -> dict[int, np.ndarray]:
    """Size -> (draws,) power of ``test`` under each bootstrap replicate of the pilot, from
    (size, first study, :func:`simulate_batch` output) triples; NaN for a replicate with no
    study."""
    hits: dict[int, np.ndarray] = {}
    seen: dict[int, np.ndarray] = {}
    for n, start, result in batches:
        flags = result[key][test]
        r = (start + np.arange(flags.size)) % draws
        hits.setdefault(n, np.zeros(draws))
        seen.setdefault(n, np.zeros(draws))
        np.add.at(hits[n], r, flags.astype(float))
        np.add.at(seen[n], r, 1.0)
    return {
        n: np.divide(hits[n], seen[n], out=np.full(draws, np.nan), where=seen[n] > 0) for n in hits
    }
