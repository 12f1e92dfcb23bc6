"""``asa calibrate``: the synthetic population fitted to a study's people (issue 39).

:func:`run_calibration` reads a study database (a pilot), checks it as ``asa power
--from-study`` does, drives a bank of synthetic participants through the study's own
protocol on Dask with the fitted blocks drawn from a wide proposal
(:mod:`study.jobs.calibrate.model`), fits the population parameters by the method of
simulated moments on that bank (:mod:`study.jobs.calibrate.fit`), bootstraps the fit on
Dask, and writes the population file (with its ``[calibration]`` table), a JSON, a text and
an HTML report beside it.
"""

from __future__ import annotations

import dataclasses
import datetime
import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.stats import norm

from sim.limits import MAX_COUNT, MAX_SEED
from study.jobs.calibrate.fit import Problem, bootstrap_fits, fit, pilot_targets
from study.jobs.calibrate.model import (
    BLOCK_FIELDS,
    BLOCKS,
    IDENTIFIES,
    PARAMETERS,
    Proposal,
    active_blocks,
    base_values,
    fitted_parameters,
    population_with,
    start_values,
)
from study.jobs.calibrate.moments import bootstrap_se, wide_frames
from study.jobs.calibrate.report import moment_rows, report_lines
from study.participants.population import Population
from study.participants.population_file import population_toml

Progress = Callable[[str, int, int], None]
SE_DRAWS = 400  # bootstrap draws of the pilot for the moments' standard errors


@dataclass(frozen=True, slots=True)
class CalibrateSettings:
    """The options of ``asa calibrate``."""

    bank: int = 300
    replicates: int = 100
    level: float = 0.95
    seed: int = 0
    scheduler: str | None = None
    workers: int = 2
    base: Population = field(default_factory=Population)


@dataclass(frozen=True, slots=True)
class CalibrationSummary:
    """What :func:`run_calibration` wrote and found."""

    out: Path  # the population file
    json: Path
    text: Path
    html: Path
    lines: tuple[str, ...]
    result: dict[str, Any]
    population: Population


def check_calibrate(s: CalibrateSettings) -> CalibrateSettings:
    """The settings; ValueError naming the flag when one is out of range."""
    for flag, value, low, high in (
        ("--bank", s.bank, 10, MAX_COUNT),
        ("--replicates", s.replicates, 10, MAX_COUNT),
        ("--seed", s.seed, 0, MAX_SEED),
        ("--workers", s.workers, 1, 1024),
    ):
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            raise ValueError(f"{flag}: must be an integer in {low}..{high}, got {value!r}")
    if not (isinstance(s.level, float) and 0.5 <= s.level < 1.0):
        raise ValueError(f"--level: must be a number in [0.5, 1), got {s.level!r}")
    return s


def _pilot(source: str):
    """(data, metric -> levels, long rows (metric, person, mode, value), people), checked as
    ``asa power --from-study`` checks a pilot."""
    from study.jobs.power.from_study import FromStudySettings, pilot_models

    data, models, longs = pilot_models(source, FromStudySettings())
    levels = {m: model.levels for m, model in models.items()}
    long = pd.concat(
        [lg.assign(metric=m, person=lg["participant"].astype(str)) for m, lg in longs.items()],
        ignore_index=True,
    )[["metric", "person", "mode", "value"]]
    people = sorted(long["person"].unique())
    if not active_blocks(levels):
        raise ValueError(
            f"{source}: no planned metric identifies a population parameter; plan one of "
            f"{', '.join(IDENTIFIES)} ([analysis] metrics; secondary_answer_time_s with "
            "secondary_baseline_level = true)"
        )
    return data, levels, long, people


def _protocol(data, source: str):
    from study.engine.protocol.parse import parse_protocol

    text = data.study.get("protocol_text") or ""
    if not text.strip():
        raise ValueError(f"{source}: field 'study.protocol_text' is empty; a pilot run by asa")
    return parse_protocol(text, f"{source} (stored protocol)")


def _bank(client, proto, s: CalibrateSettings, blocks, path: Path, say: Progress):
    """Drive (or continue) the calibration bank; (entries, long outcome rows)."""
    import study
    from study.jobs.power.bank import BankFile
    from study.jobs.power.run import PowerSettings, build_bank

    identity = {
        "protocol_sha256": proto.sha256, "seed": s.seed, "blocks": list(blocks),
        "population": dataclasses.asdict(s.base), "platform_version": study.__version__,
    }  # fmt: skip
    bank = BankFile(path, identity, resume=True)
    try:
        power = PowerSettings(sizes=(2,), studies=1, bank=s.bank, seed=s.seed, population=s.base)
        wall = build_bank(client, bank, proto, power, say, Proposal(blocks))
        entries, outcomes = bank.frames(s.bank)
    finally:
        bank.close()
    return entries, outcomes.assign(person=outcomes["entry"]), wall


def _problem(s, blocks, levels, pilot_long, people, entries, bank_long, rng) -> Problem:
    params = [json.loads(p) for p in entries["parameters"]]
    fields = [f for b in blocks for f in BLOCK_FIELDS[b]]
    values = {f: np.array([float(p[f]) for p in params]) for f in fields}
    pilot = wide_frames(pilot_long, people, levels)
    return Problem(
        params=fitted_parameters(blocks), blocks=blocks, fixed=base_values(s.base),
        pilot=pilot, pilot_people=len(people),
        bank=wide_frames(bank_long, list(entries["entry"]), levels), bank_values=values,
        se=bootstrap_se(pilot, len(people), SE_DRAWS, rng),
    )  # fmt: skip


def _bootstrap(client, problem: Problem, estimate, s: CalibrateSettings, say) -> np.ndarray:
    """(R, p) bootstrap fits, in chunks on the cluster."""
    from distributed import as_completed

    spawned = np.random.SeedSequence(s.seed).spawn(s.replicates)
    seeds = [int(q.generate_state(1)[0]) for q in spawned]
    size = max(1, math.ceil(s.replicates / (4 * s.workers)))
    chunks = [seeds[i : i + size] for i in range(0, len(seeds), size)]
    shared = client.scatter(problem, broadcast=True)
    futures = {client.submit(bootstrap_fits, shared, estimate, c, pure=False): i
               for i, c in enumerate(chunks)}  # fmt: skip
    out, done = {}, 0
    say("replicates", 0, s.replicates)
    try:
        for future in as_completed(list(futures)):
            out[futures[future]] = future.result()
            done += len(chunks[futures[future]])
            say("replicates", done, s.replicates)
    finally:
        client.cancel(list(futures))
    return np.vstack([out[i] for i in range(len(chunks))])


def run_calibration(
    source: str | Path,
    out: str | Path,
    settings: CalibrateSettings | None = None,
    *,
    progress: Progress | None = None,
) -> CalibrationSummary:
    """Fit the synthetic population to a study's people.

    Parameters
    ----------
    source : the study database (file or URL) or ``asa export`` folder.
    out : the population file to write (TOML); ``.json``, ``.txt`` and ``.html`` reports and
        the bank (``<stem>_bank.sqlite``, continued by a later run with the same settings)
        beside it.
    settings : :class:`CalibrateSettings`.
    progress : called with (stage, done, total); stage "bank" or "replicates".

    Raises
    ------
    ValueError
        Bad settings (naming the flag), a study that cannot be calibrated to (naming the
        file and field: a planned metric without values, fewer than 3 complete people).
    """
    from study.jobs.power.cluster import dask_engine

    start = time.perf_counter()
    s = check_calibrate(settings if settings is not None else CalibrateSettings())
    say = progress if progress is not None else (lambda stage, done, total: None)
    data, levels, pilot_long, people = _pilot(str(source))
    proto = _protocol(data, str(source))
    blocks = active_blocks(levels)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with dask_engine(s.scheduler, s.workers) as engine:
        bank_path = out.with_name(out.stem + "_bank.sqlite")
        entries, bank_long, bank_s = _bank(engine.client, proto, s, blocks, bank_path, say)
        rng = np.random.default_rng(s.seed)
        problem = _problem(s, blocks, levels, pilot_long, people, entries, bank_long, rng)
        t0 = time.perf_counter()
        starts = [start_values(s.base, problem.params)]
        starts.append(np.array([(p.bounds[0] + p.bounds[1]) / 2 for p in problem.params]))
        targets = pilot_targets(problem)
        estimate = fit(problem, targets, np.ones(len(entries)), starts)
        reps = _bootstrap(engine.client, problem, estimate, s, say)
        fit_s = time.perf_counter() - t0
    timing = {"bank_s": bank_s, "fit_s": fit_s, "total_s": time.perf_counter() - start}
    result = _result(data, str(source), s, engine.description, problem, estimate, reps, timing)
    population = population_with(s.base, blocks, result["values"])
    return _write(out, population, result)


def _intervals(problem: Problem, estimate, reps, level: float) -> list[dict[str, Any]]:
    z = float(norm.ppf(0.5 + level / 2.0))
    rows = []
    for j, p in enumerate(problem.params):
        sd = float(np.std(reps[:, j], ddof=1))
        low = max(p.bounds[0], float(estimate[j]) - z * sd)
        high = min(p.bounds[1], float(estimate[j]) + z * sd)
        rows.append({
            "name": p.name, "unit": p.unit, "meaning": p.meaning, "block": p.block,
            "estimate": float(estimate[j]), "low": low, "high": high, "bootstrap_sd": sd,
            "percentile": [float(np.quantile(reps[:, j], q)) for q in (0.5 - level / 2,
                                                                     0.5 + level / 2)],
            "base": float(problem.fixed[p.name]), "search": list(p.bounds),
        })  # fmt: skip
    return rows


def _result(data, source, s, engine, problem, estimate, reps, timing) -> dict[str, Any]:
    import study

    params = _intervals(problem, estimate, reps, s.level)
    return {
        "title": f"Calibration of the synthetic population to {data.study['name']}",
        "created_at": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "platform_version": study.__version__,
        "study": {
            "file": source,
            "name": str(data.study["name"]),
            "protocol_sha256": str(data.study["protocol_sha256"]),
            "participants": problem.pilot_people,
        },  # fmt: skip
        "settings": {
            "bank": s.bank,
            "replicates": s.replicates,
            "level": s.level,
            "seed": s.seed,
            "engine": engine,
            "se_draws": SE_DRAWS,
        },  # fmt: skip
        "method": "simulated moments, importance-weighted bank, Nelder-Mead; "
        "bootstrap of participants and bank entries",
        "blocks": list(problem.blocks),
        "identified_by": {b: [m for m, i in IDENTIFIES.items() if i == b] for b in BLOCKS},
        "not_fitted": [
            {
                "name": p.name,
                "block": p.block,
                "unit": p.unit,
                "meaning": p.meaning,
                "base": float(problem.fixed[p.name]),
            }
            for p in PARAMETERS
            if p.block not in problem.blocks
        ],  # fmt: skip
        "parameters": params,
        "values": {p["name"]: p["estimate"] for p in params},
        "moments": moment_rows(problem, estimate),
        "timing": timing,
    }


def _write(out: Path, population: Population, result: dict) -> CalibrationSummary:
    from analysis.calibration_report import write_calibration_report  # matplotlib: lazily

    calibration = {
        "method": result["method"], "study": result["study"]["file"],
        "study_name": result["study"]["name"],
        "protocol_sha256": result["study"]["protocol_sha256"],
        "participants": result["study"]["participants"], "bank": result["settings"]["bank"],
        "replicates": result["settings"]["replicates"], "level": result["settings"]["level"],
        "seed": result["settings"]["seed"], "created_at": result["created_at"],
        "platform_version": result["platform_version"],
        "fitted": [p["name"] for p in result["parameters"]],
    }  # fmt: skip
    for p in result["parameters"]:
        calibration[f"{p['name']}_interval"] = [p["low"], p["high"]]
    out.write_text(population_toml(population, calibration), encoding="utf-8")
    lines = tuple(report_lines(result))
    json_path, text_path = out.with_suffix(".json"), out.with_suffix(".txt")
    json_path.write_text(json.dumps(result, indent=1, allow_nan=True) + "\n", encoding="utf-8")
    text_path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    html = write_calibration_report(result, out)
    return CalibrationSummary(out, json_path, text_path, html, lines, result, population)
