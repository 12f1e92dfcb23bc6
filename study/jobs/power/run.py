"""``asa power``: simulation-based power analysis of a protocol (issue 22).

:func:`run_power` builds (or continues) the participant bank on Dask
(:mod:`study.jobs.power.bank`), resamples studies of every size from it in batches on Dask
(:mod:`analysis.power.resample`), and writes ``power.json``, ``power.html`` and
``power_curves.png/svg`` into the output folder (:mod:`analysis.power.report`).
"""

from __future__ import annotations

import dataclasses
import datetime
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from analysis.data import BASELINE
from analysis.metrics import BY_NAME
from analysis.power import (
    OMNIBUS,
    Batch,
    PlannedTests,
    bank_effects,
    check_size,
    curve,
    n_for_power,
    resample_batch,
    slot_pools,
    summary_lines,
    tally,
)
from sim.limits import MAX_COUNT, MAX_SEED
from study.engine.counterbalance import SlotOrders, cycle_length
from study.engine.protocol import POSTHOC_GATES, Protocol, load_protocol
from study.jobs.power.bank import BANK_FILE, BankFile, bank_jobs, bank_root, run_entry
from study.jobs.power.cluster import dask_engine
from study.participants.synthetic import Population

Progress = Callable[[str, int, int], None]  # (stage, done, total)
BATCH_STUDIES = 25  # resampled studies per Dask task


@dataclass(frozen=True, slots=True)
class PowerSettings:
    """The options of one power analysis (``asa power``'s flags)."""

    sizes: tuple[int, ...] = (6, 12, 18, 24)
    studies: int = 1000
    bank: int = 300
    seed: int = 0
    scheduler: str | None = None
    workers: int = 2
    resume: bool = False
    population: Population = dataclasses.field(default_factory=Population)
    posthoc_gate: str | None = None  # analysis.stats.POSTHOC_GATES; None: the protocol's


@dataclass(frozen=True, slots=True)
class PowerSummary:
    """What :func:`run_power` wrote and found."""

    out: Path
    json: Path
    html: Path
    lines: tuple[str, ...]  # the one-screen summary
    result: dict[str, Any]  # the contents of power.json


def check_settings(s: PowerSettings) -> PowerSettings:
    """The settings, sizes sorted; ValueError naming the flag when one is out of range."""
    sizes = tuple(s.sizes)
    if not sizes or any(isinstance(n, bool) or not isinstance(n, int) or n < 2 for n in sizes):
        raise ValueError(f"--sizes: must be integers >= 2 separated by commas, got {sizes!r}")
    for flag, value, low, high in (
        ("--studies", s.studies, 1, MAX_COUNT),
        ("--bank", s.bank, 2, MAX_COUNT),
        ("--seed", s.seed, 0, MAX_SEED),
        ("--workers", s.workers, 1, 1024),
    ):
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            raise ValueError(f"{flag}: must be an integer in {low}..{high}, got {value!r}")
    if s.posthoc_gate is not None and s.posthoc_gate not in POSTHOC_GATES:
        raise ValueError(
            f"--posthoc-gate: must be one of {', '.join(POSTHOC_GATES)}, got {s.posthoc_gate!r}"
        )
    if max(sizes) > s.bank:
        raise ValueError(
            f"--sizes: N = {max(sizes)} is larger than the bank ({s.bank} participants); "
            f"use a larger --bank"
        )
    return dataclasses.replace(s, sizes=tuple(sorted(set(sizes))))


def slot_rows(proto: Protocol, count: int) -> list[int] | None:
    """The counterbalancing row of slots 0 .. count - 1 (None for the random scheme)."""
    if proto.counterbalancing == "random":
        return None
    orders = SlotOrders(proto.modes, proto.counterbalancing, proto.study.seed)
    return [orders.row(j) for j in range(count)]


def run_power(
    protocol: Protocol | str | Path,
    out: str | Path,
    settings: PowerSettings | None = None,
    *,
    progress: Progress | None = None,
) -> PowerSummary:
    """Simulation-based power of every planned test of ``protocol``.

    Parameters
    ----------
    protocol : a loaded protocol, or a shipped name / TOML file.
    out : folder for ``bank.sqlite``, ``power.json``, ``power.html``, ``power_curves.*``
        (created).
    settings : sizes, studies per size, bank size, seed, the Dask engine, resume and the
        population model (:class:`PowerSettings`; default its defaults).
    progress : called with (stage, done, total) as bank entries and batches of studies
        finish; stage "bank" or "studies".

    Returns
    -------
    PowerSummary

    Raises
    ------
    ValueError
        Bad settings (naming the flag), a bank file of another protocol, seed, population
        or platform version, an existing bank without ``resume``, an unreachable scheduler.
    """
    start = time.perf_counter()
    s = check_settings(settings if settings is not None else PowerSettings())
    proto = load_protocol(protocol) if isinstance(protocol, str | Path) else protocol
    slots = slot_rows(proto, max(s.sizes))
    say = progress if progress is not None else (lambda stage, done, total: None)
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    bank = BankFile(folder / BANK_FILE, _identity(proto, s), resume=s.resume)
    try:
        with dask_engine(s.scheduler, s.workers) as engine:
            bank_s = build_bank(engine.client, bank, proto, s, say)
            entries, outcomes = bank.frames(s.bank)
            for n in s.sizes:  # bank entry i drove slot i's order: always enough
                check_size(slot_pools(entries, slots), slots, n)
            planned = _planned(proto, outcomes, s.posthoc_gate)
            t0 = time.perf_counter()
            batches = _resample(engine.client, outcomes, entries, planned, s, slots, say)
            resample_s = time.perf_counter() - t0
    finally:
        bank.close()
    counts = tally(batches, planned)
    timing = {"bank_s": bank_s, "resample_s": resample_s}
    result = _result(proto, s, engine.description, entries, outcomes, planned, counts, timing)
    result["timing"]["total_s"] = time.perf_counter() - start
    return _write(folder, result)


def _identity(proto: Protocol, s: PowerSettings) -> dict[str, Any]:
    """What a bank file must agree on to be continued."""
    import study

    return {
        "protocol_sha256": proto.sha256,
        "protocol": proto.name,
        "seed": s.seed,
        "population": dataclasses.asdict(s.population),
        "platform_version": study.__version__,
    }


def build_bank(
    client, bank: BankFile, proto: Protocol, s: PowerSettings, say: Progress, proposal=None
) -> float:
    """Drive the bank entries not yet in the bank file; each stored as it completes
    (``proposal``: see :func:`study.jobs.power.bank.bank_jobs`)."""
    from distributed import as_completed

    start = time.perf_counter()
    stored = bank.done()
    todo = [i for i in range(s.bank) if i not in stored]
    total, done = s.bank, s.bank - len(todo)
    say("bank", done, total)
    futures = [
        client.submit(run_entry, job, pure=False, key=f"bank-{job.index}-{job.session_seed}")
        for job in bank_jobs(proto, s.seed, todo, s.population, proposal)
    ]
    try:
        for future in as_completed(futures):
            bank.add(future.result())
            done += 1
            say("bank", done, total)
    finally:
        client.cancel(futures)
    return time.perf_counter() - start


def _planned(proto: Protocol, outcomes, posthoc_gate: str | None = None) -> PlannedTests:
    """The planned tests of every metric in the bank, levels in report order;
    ``posthoc_gate`` overrides the protocol's."""
    a = proto.analysis
    metrics = {}
    for metric in a.metrics:
        seen = set(outcomes.loc[outcomes["metric"] == metric, "mode"])
        levels = [m for m in proto.modes if m in seen] + ([BASELINE] if BASELINE in seen else [])
        if len(levels) >= 2:
            metrics[metric] = tuple(levels)
    tests = {m: a.test_for(m) for m in metrics}
    return PlannedTests(
        metrics, alpha=a.alpha, gate=a.gate, posthoc=a.posthoc, tests=tests,
        posthoc_gate=posthoc_gate if posthoc_gate is not None else a.posthoc_gate,
    )  # fmt: skip


def _resample(
    client,
    outcomes,
    entries,
    planned: PlannedTests,
    s: PowerSettings,
    slots: Sequence[int] | None,
    say: Progress,
) -> list[tuple[int, dict]]:
    """Every size's studies, in batches of :data:`BATCH_STUDIES`, on the cluster."""
    from distributed import as_completed

    shared_outcomes, shared_entries = client.scatter([outcomes, entries], broadcast=True)
    batches = [
        Batch(n, a, min(a + BATCH_STUDIES, s.studies))
        for n in s.sizes
        for a in range(0, s.studies, BATCH_STUDIES)
    ]
    futures = {
        client.submit(
            resample_batch, shared_outcomes, shared_entries, planned, b,
            seed=s.seed, slot_rows=slots, pure=False,
        ): b
        for b in batches
    }  # fmt: skip
    out, done, total = [], 0, s.studies * len(s.sizes)
    say("studies", done, total)
    try:
        for future in as_completed(list(futures)):
            b = futures[future]
            out.append((b.n, future.result()))
            done += b.stop - b.start
            say("studies", done, total)
    finally:
        client.cancel(list(futures))
    return sorted(out, key=lambda item: item[0])


def _result(
    proto: Protocol,
    s: PowerSettings,
    engine: str,
    entries,
    outcomes,
    planned: PlannedTests,
    counts: dict,
    timing: dict[str, float],
) -> dict[str, Any]:
    """The contents of power.json (the report's input)."""
    import study

    metrics = [_metric(m, planned, counts[m], outcomes) for m in planned.metrics]
    cpu_s = float(entries["cpu_s"].sum())
    trials = int(entries["main_trials"].sum())
    studies = s.studies * len(s.sizes)
    a = proto.analysis
    return {
        "title": f"Power analysis: {proto.study.title or proto.name}",
        "created_at": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "platform_version": study.__version__,
        "protocol": {
            "name": proto.name,
            "title": proto.study.title,
            "sha256": proto.sha256,
            "source": proto.source,
            "modes": list(proto.modes),
            "counterbalancing": proto.counterbalancing,
            "cycle": cycle_length(len(proto.modes), proto.counterbalancing),
        },  # fmt: skip
        "settings": {
            "sizes": list(s.sizes),
            "studies": s.studies,
            "bank": s.bank,
            "seed": s.seed,
            "alpha": a.alpha,
            "gate": a.gate,
            "posthoc": a.posthoc,
            "posthoc_gate": planned.posthoc_gate,
            "tests": dict(planned.tests),
            "target_power": 0.8,
            "ci_level": 0.95,
            "engine": engine,
        },  # fmt: skip
        "bank": {
            "file": BANK_FILE,
            "entries": int(len(entries)),
            "statuses": {str(k): int(v) for k, v in entries["status"].value_counts().items()},
            "main_trials": trials,
            "timed_out_trials": int(entries["timed_out"].sum()),
            "simulated_s": float(entries["simulated_s"].sum()),
            "cpu_s": cpu_s,
            "seed_root": bank_root(proto),
            "population": dataclasses.asdict(s.population),
        },  # fmt: skip
        "metrics": metrics,
        "summary": summary_lines(metrics),
        "timing": {
            **timing,
            "bank_trials_per_cpu_s": trials / cpu_s if cpu_s > 0 else None,
            "studies_per_s": studies / timing["resample_s"] if timing["resample_s"] else None,
        },
    }


def _metric(metric: str, planned: PlannedTests, counts: dict, outcomes) -> dict[str, Any]:
    """One metric's entry of power.json."""
    tests = []
    for key in planned.keys(metric):
        points = curve(counts[key])
        a, b = (None, None) if key == OMNIBUS else key.split(" vs ", 1)
        tests.append(
            {"test": key, "a": a, "b": b, "curve": points, "n_for_power": n_for_power(points)}
        )
    return {
        "metric": metric,
        "label": BY_NAME[metric].label,
        "levels": list(planned.metrics[metric]),
        "failed": {str(n): k for n, (k, _) in sorted(counts["_failed"].items())},
        "effects": bank_effects(outcomes, planned, metric),
        "tests": tests,
    }


def _write(folder: Path, result: dict[str, Any]) -> PowerSummary:
    """power.json and the report."""
    from analysis.power.report import write_power_report

    path = folder / "power.json"
    path.write_text(json.dumps(result, indent=1, allow_nan=False) + "\n", encoding="utf-8")
    paths = write_power_report(result, folder)
    return PowerSummary(
        out=folder, json=path, html=paths.html, lines=tuple(result["summary"]), result=result
    )
