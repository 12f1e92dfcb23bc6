"""``asa power --from-study``: power planned from a pilot's own data (issue 39).

:func:`run_power_from_study` reads a study database (a pilot with people, or any study),
fits per planned metric the model of the study's analysis to its complete participants
(:mod:`analysis.power.parametric`), simulates studies of every size from it on Dask in
batches (the pilot's estimates, the pilot's uncertainty by a bootstrap over its
participants, and each stated smallest effect of interest) and analyses each with the
protocol's planned chain, then writes ``power.json``, ``power.html`` and
``power_curves.png/svg`` as ``asa power`` does.
"""

from __future__ import annotations

import dataclasses
import datetime
import time
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from analysis.data import load_study, tidy
from analysis.metrics import BY_NAME, long_frame
from analysis.power import Batch, PlannedTests, curve, n_for_power, summary_lines, tally
from analysis.power.parametric import (
    MIN_PILOT,
    MODELS,
    PilotModel,
    at_effect,
    replicate_powers,
    simulate_batch,
    split_key,
    variant_key,
)
from analysis.power.summary import bank_effects
from analysis.presentation import without_constant_levels
from analysis.stats import POSTHOC_GATES, repeated_measures
from sim.limits import MAX_COUNT, MAX_SEED
from study.engine.counterbalance import cycle_length
from study.jobs.power.cluster import dask_engine
from study.jobs.power.run import BATCH_STUDIES, PowerSummary, _write

Progress = Callable[[str, int, int], None]
SPREAD = (0.1, 0.9)  # quantiles of the bootstrap replicates' power reported


@dataclass(frozen=True, slots=True)
class FromStudySettings:
    """The options of ``asa power --from-study``."""

    sizes: tuple[int, ...] = (6, 12, 18, 24)
    studies: int = 1000
    seed: int = 0
    metrics: tuple[str, ...] = ()  # empty: every planned metric
    interest: Mapping[str, float] = field(default_factory=dict)  # metric -> SESOI
    model: str = "mvn"
    draws: int = 50  # bootstrap replicates of the pilot
    scheduler: str | None = None
    workers: int = 2
    posthoc_gate: str | None = None


def check_from_study(s: FromStudySettings) -> FromStudySettings:
    """The settings, sizes sorted; ValueError naming the flag when one is out of range."""
    sizes = tuple(s.sizes)
    if not sizes or any(isinstance(n, bool) or not isinstance(n, int) or n < 3 for n in sizes):
        raise ValueError(f"--sizes: must be integers >= 3 separated by commas, got {sizes!r}")
    for flag, value, low, high in (
        ("--studies", s.studies, 1, MAX_COUNT),
        ("--seed", s.seed, 0, MAX_SEED),
        ("--workers", s.workers, 1, 1024),
        ("--draws", s.draws, 2, MAX_COUNT),
    ):
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            raise ValueError(f"{flag}: must be an integer in {low}..{high}, got {value!r}")
    if s.model not in MODELS:
        raise ValueError(f"--model: must be one of {', '.join(MODELS)}, got {s.model!r}")
    if s.posthoc_gate is not None and s.posthoc_gate not in POSTHOC_GATES:
        raise ValueError(
            f"--posthoc-gate: must be one of {', '.join(POSTHOC_GATES)}, got {s.posthoc_gate!r}"
        )
    for metric, value in s.interest.items():
        if not np.isfinite(value) or value <= 0:
            raise ValueError(
                f"--effect-of-interest: {metric}={value!r}: the value must be a positive "
                "difference in the metric's units"
            )
    return dataclasses.replace(s, sizes=tuple(sorted(set(sizes))))


def pilot_models(source: str, s: FromStudySettings) -> tuple[Any, dict[str, PilotModel], dict]:
    """(the study's data, metric -> fitted :class:`PilotModel`, metric -> its long frame).

    Raises ValueError naming ``source`` and the metric: a metric not planned, no values of
    a planned metric, fewer than :data:`MIN_PILOT` complete participants.
    """
    data = load_study(source)
    cfg = data.config
    chosen = s.metrics or cfg.metrics
    for metric in (*chosen, *s.interest):
        if metric not in cfg.metrics:
            raise ValueError(
                f"{source}: metric {metric!r} is not planned by the study's protocol "
                f"([analysis] metrics: {', '.join(cfg.metrics) or 'none'})"
            )
    for metric in s.interest:
        if metric not in chosen:
            raise ValueError(
                f"--effect-of-interest: {metric} is not among the metrics simulated "
                f"({', '.join(chosen)}); add --metric {metric}"
            )
    frames = tidy(data)
    models, longs = {}, {}
    for metric in chosen:
        long = long_frame(frames, metric, baseline=cfg.secondary_baseline_level)
        long, _ = without_constant_levels(BY_NAME[metric], long)
        if long.empty or long["value"].notna().sum() == 0 or long["mode"].nunique() < 2:
            raise ValueError(
                f"{source}: planned metric {metric!r} has no values in two levels or more "
                "(field trial." + metric + "); a pilot must measure every planned metric"
            )
        rm = repeated_measures(long, dv="value", within="mode", subject="participant")
        if rm.y.shape[0] < MIN_PILOT:
            raise ValueError(
                f"{source}: planned metric {metric!r} has {rm.y.shape[0]} complete "
                f"participants (every level measured); at least {MIN_PILOT} are needed"
            )
        interest = s.interest.get(metric)
        model = PilotModel(metric, tuple(rm.levels), rm.y, kind=s.model, interest=interest)
        if interest is not None:
            at_effect(model.fit()[0], interest)  # refuses a pilot without differences
        models[metric], longs[metric] = model, long
    return data, models, longs


def _planned(cfg, models: Mapping[str, PilotModel], s: FromStudySettings) -> PlannedTests:
    """The planned tests of every variant key: the pilot's estimates, its uncertainty, and
    the effect of interest where one is stated."""
    metrics, tests = {}, {}
    for metric, model in models.items():
        variants = ["pilot", "uncertain"] + (["interest"] if model.interest is not None else [])
        for v in variants:
            metrics[variant_key(metric, v)] = model.levels
            tests[variant_key(metric, v)] = cfg.test_for(metric)
    gate = s.posthoc_gate if s.posthoc_gate is not None else cfg.posthoc_gate
    return PlannedTests(
        metrics, alpha=cfg.alpha, gate=cfg.gate, posthoc=cfg.posthoc, tests=tests,
        posthoc_gate=gate,
    )  # fmt: skip


def run_power_from_study(
    source: str | Path,
    out: str | Path,
    settings: FromStudySettings | None = None,
    *,
    progress: Progress | None = None,
) -> PowerSummary:
    """Power of every planned test of a study's protocol from the study's own data.

    Parameters
    ----------
    source : the pilot's database (file or URL) or ``asa export`` folder.
    out : folder for ``power.json``, ``power.html``, ``power_curves.*`` (created).
    settings : :class:`FromStudySettings`.
    progress : called with ("studies", done, total).

    Raises
    ------
    ValueError
        Bad settings (naming the flag) or a pilot that cannot be modelled (naming the file
        and metric).
    """
    start = time.perf_counter()
    s = check_from_study(settings if settings is not None else FromStudySettings())
    data, models, longs = pilot_models(str(source), s)
    planned = _planned(data.config, models, s)
    say = progress if progress is not None else (lambda stage, done, total: None)
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    with dask_engine(s.scheduler, s.workers) as engine:
        t0 = time.perf_counter()
        batches = _simulate(engine.client, models, planned, s, say)
        simulate_s = time.perf_counter() - t0
    result = _result(data, str(source), s, engine.description, models, longs, planned, batches)
    result["timing"] = {
        "simulate_s": simulate_s,
        "studies_per_s": len(planned.metrics) * s.studies * len(s.sizes) / simulate_s,
        "total_s": time.perf_counter() - start,
    }
    return _write(folder, result)


def _simulate(client, models, planned: PlannedTests, s: FromStudySettings, say: Progress):
    """Every size's studies of every variant, in batches of :data:`BATCH_STUDIES`, on the
    cluster; (size, first study, batch result) triples."""
    from distributed import as_completed

    shared = client.scatter(models, broadcast=True)
    batches = [
        Batch(n, a, min(a + BATCH_STUDIES, s.studies))
        for n in s.sizes
        for a in range(0, s.studies, BATCH_STUDIES)
    ]
    futures = {
        client.submit(simulate_batch, shared, planned, b, seed=s.seed, draws=s.draws, pure=False): b
        for b in batches
    }
    out, done, total = [], 0, s.studies * len(s.sizes)
    say("studies", done, total)
    try:
        for future in as_completed(list(futures)):
            b = futures[future]
            out.append((b.n, b.start, future.result()))
            done += b.stop - b.start
            say("studies", done, total)
    finally:
        client.cancel(list(futures))
    return sorted(out, key=lambda item: (item[0], item[1]))


_VARIANT_WORDS = {
    "pilot": "at the pilot's estimates",
    "uncertain": "over the pilot's uncertainty (bootstrap)",
    "interest": "at the smallest effect of interest",
}


def _protocol_block(data, source: str) -> dict[str, Any]:
    """What the pilot's stored protocol says about itself (for the report's header)."""
    doc = tomllib.loads(data.study.get("protocol_text") or "")
    modes = tuple(data.config.modes)
    scheme = str((doc.get("modes") or {}).get("counterbalancing", "full_permutation"))
    return {
        "name": str(data.study["name"]),
        "title": str((doc.get("study") or {}).get("title") or data.study["name"]),
        "sha256": str(data.study["protocol_sha256"]),
        "source": source,
        "modes": list(modes),
        "counterbalancing": scheme,
        "cycle": cycle_length(len(modes), scheme) if len(modes) >= 2 else None,
    }


def _pilot_block(data, source: str, models: Mapping[str, PilotModel]) -> dict[str, Any]:
    """The pilot: who took part and, per metric, the fitted model's moments."""
    people = data.tables["participant"]
    kinds = {str(k): int(v) for k, v in people["kind"].value_counts().items()}
    fitted = {}
    for metric, model in models.items():
        mean, cov = model.fit()
        sd = np.sqrt(np.diag(cov))
        corr = cov / np.outer(sd, sd) if np.all(sd > 0) else np.full_like(cov, np.nan)
        fitted[metric] = {
            "n": int(model.wide.shape[0]),
            "levels": list(model.levels),
            "mean": [float(v) for v in mean],
            "sd": [float(v) for v in sd],
            "covariance": [[float(v) for v in row] for row in cov],
            "correlation": [[None if np.isnan(v) else float(v) for v in row] for row in corr],
            "interest": model.interest,
        }
    return {"file": source, "participants": int(len(people)), "kinds": kinds, "fitted": fitted}


def _metric_entry(key: str, planned: PlannedTests, counts: dict, batches, s, effects):
    """One variant key's entry of power.json (as ``asa power``'s, plus ``variant``)."""
    metric, variant = split_key(key)
    tests = []
    for test in planned.keys(key):
        points = curve(counts[test])
        a, b = (None, None) if test == "omnibus" else test.split(" vs ", 1)
        entry = {"test": test, "a": a, "b": b, "curve": points, "n_for_power": n_for_power(points)}
        if variant == "uncertain":
            powers = replicate_powers(batches, key, test, s.draws)
            entry["replicates"] = [
                {"n": n, "low": float(np.nanquantile(p, SPREAD[0])),
                 "median": float(np.nanmedian(p)), "high": float(np.nanquantile(p, SPREAD[1]))}
                for n, p in sorted(powers.items())
            ]  # fmt: skip
        tests.append(entry)
    return {
        "metric": key,
        "base_metric": metric,
        "variant": variant,
        "label": f"{BY_NAME[metric].label}, {_VARIANT_WORDS[variant]}",
        "levels": list(planned.metrics[key]),
        "failed": {str(n): k for n, (k, _) in sorted(counts["_failed"].items())},
        "effects": effects if variant == "pilot" else None,
        "tests": tests,
    }


def _result(data, source, s, engine, models, longs, planned, batches) -> dict[str, Any]:
    """The contents of power.json for a pilot (the report's input; ``source`` "pilot")."""
    import study

    counts = tally([(n, r) for n, _, r in batches], planned)
    metrics = []
    for key in planned.metrics:
        metric, _ = split_key(key)
        frame = longs[metric].assign(metric=key)
        effects = bank_effects(frame, planned, key)
        metrics.append(_metric_entry(key, planned, counts[key], batches, s, effects))
    cfg = data.config
    return {
        "source": "pilot",
        "title": f"Power from a pilot: {data.study['name']}",
        "created_at": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "platform_version": study.__version__,
        "protocol": _protocol_block(data, source),
        "settings": {
            "sizes": list(s.sizes),
            "studies": s.studies,
            "seed": s.seed,
            "model": s.model,
            "draws": s.draws,
            "interest": dict(s.interest),
            "alpha": cfg.alpha,
            "gate": cfg.gate,
            "posthoc": cfg.posthoc,
            "posthoc_gate": planned.posthoc_gate,
            "tests": {m: cfg.test_for(m) for m in models},
            "target_power": 0.8,
            "ci_level": 0.95,
            "spread": list(SPREAD),
            "engine": engine,
        },  # fmt: skip
        "pilot": _pilot_block(data, source, models),
        "metrics": metrics,
        "summary": summary_lines(metrics),
    }
