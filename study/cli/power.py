"""``asa power``: how many participants each planned test of a protocol needs, by
simulation (:func:`study.jobs.power.run_power`, issue 22). A bank of synthetic participants
is driven on Dask (a local cluster of worker processes by default, any Dask scheduler with
``--scheduler``) and stored as it completes in ``OUT/bank.sqlite``; ``--resume`` continues a
bank cut short. Studies of each size are resampled from the bank and analysed as the
protocol plans. A progress bar (done / total, ETA) goes to stderr; the one-screen summary
to stdout."""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import TextIO

import click

from study.cli import COUNT, SEED, WORKERS

STAGES = {
    "bank": "bank participants",
    "studies": "resampled studies",
    "replicates": "bootstrap replicates",
}
LOG_EVERY_S = 30.0  # [s] between progress lines when stderr is not a terminal


class ProgressBar:
    """``bank participants [#####-----] 120/300  40 %  12:31 elapsed, ETA 18:40``, rewritten
    in place on a terminal, else a line at most every :data:`LOG_EVERY_S`. The ETA is the
    rate of this run (entries already in a resumed bank do not count)."""

    def __init__(self, stream: TextIO | None = None, width: int = 30) -> None:
        self.stream = stream if stream is not None else sys.stderr
        self.tty = self.stream.isatty()
        self.width = width
        self.stage = ""
        self.first = (0.0, 0)  # (time, done) at the stage's first report
        self.last_line = 0.0

    def __call__(self, stage: str, done: int, total: int) -> None:
        now = time.monotonic()
        if stage != self.stage:
            if self.stage and self.tty:
                self.stream.write("\n")
            self.stage, self.first, self.last_line = stage, (now, done), 0.0
        line = self.line(stage, done, total, now)
        if self.tty:
            self.stream.write("\r" + line)
            if done >= total:
                self.stream.write("\n")
                self.stage = ""
        elif done >= total or now - self.last_line >= LOG_EVERY_S:
            self.stream.write(line + "\n")
            self.last_line = now
        self.stream.flush()

    def line(self, stage: str, done: int, total: int, now: float) -> str:
        filled = int(self.width * done / total) if total else self.width
        bar = "#" * filled + "-" * (self.width - filled)
        t0, d0 = self.first
        elapsed = now - t0
        eta = "--:--"
        if done > d0 and done < total:
            eta = _clock(elapsed / (done - d0) * (total - done))
        elif done >= total:
            eta = "done"
        percent = 100.0 * done / total if total else 100.0
        return (
            f"{STAGES.get(stage, stage)} [{bar}] {done}/{total} {percent:3.0f} %  "
            f"{_clock(elapsed)} elapsed, ETA {eta}"
        )


def _clock(seconds: float) -> str:
    minutes, s = divmod(int(round(seconds)), 60)
    hours, m = divmod(minutes, 60)
    return f"{hours}:{m:02d}:{s:02d}" if hours else f"{m:02d}:{s:02d}"


def _sizes(value: str) -> tuple[int, ...]:
    parts = [p.strip() for p in value.split(",") if p.strip()]
    if not parts or not all(p.isdigit() and int(p) >= 2 for p in parts):
        raise ValueError(
            f"--sizes: must be integers >= 2 separated by commas (e.g. 6,12,18,24), got {value!r}"
        )
    return tuple(int(p) for p in parts)


def _interest(values: tuple[str, ...]) -> dict[str, float]:
    """``("score_s=20", ...)`` -> {"score_s": 20.0}."""
    out = {}
    for item in values:
        name, sep, number = item.partition("=")
        try:
            value = float(number) if sep and name.strip() else None
        except ValueError:
            value = None
        if value is None:
            raise ValueError(
                f"--effect-of-interest: expected METRIC=VALUE (e.g. score_s=20), got {item!r}"
            )
        out[name.strip()] = value
    return out


@click.command("power")
@click.option("--protocol", default=None, help="Shipped protocol name or TOML file.")
@click.option(
    "--from-study",
    "from_study",
    default=None,
    metavar="DB",
    help="Plan from a pilot's data instead of a bank: a study database (file or URL) whose "
    "protocol's planned metrics are fitted and simulated (parametric bootstrap).",
)
@click.option(
    "--metric",
    "metrics",
    multiple=True,
    help="With --from-study: only this planned metric (repeat for several; default all).",
)
@click.option(
    "--effect-of-interest",
    "interest",
    multiple=True,
    metavar="METRIC=VALUE",
    help="With --from-study: power also at this smallest effect of interest (the largest "
    "difference between two levels, in the metric's units), e.g. score_s=20.",
)
@click.option(
    "--model",
    type=click.Choice(("mvn", "lmm")),
    default="mvn",
    show_default=True,
    help="With --from-study: the model fitted to the pilot: mvn = mode means and "
    "unstructured covariance (the RM-ANOVA's), lmm = random intercept per participant.",
)
@click.option(
    "--draws",
    type=COUNT,
    default=50,
    show_default=True,
    help="With --from-study: bootstrap replicates of the pilot (its uncertainty).",
)
@click.option(
    "--sizes",
    default="6,12,18,24",
    show_default=True,
    help="Sample sizes N to simulate, comma-separated (each at most --bank).",
)
@click.option(
    "--studies", type=COUNT, default=1000, show_default=True, help="Resampled studies per size."
)
@click.option(
    "--bank",
    type=COUNT,
    default=None,
    help="Synthetic participants in the bank (each drives one main trial per mode); default 300.",
)
@click.option("--seed", type=SEED, default=0, show_default=True, help="Seed of bank and studies.")
@click.option(
    "--scheduler",
    default=None,
    metavar="ADDRESS",
    help="A running Dask scheduler (tcp://host:8786); default a local cluster.",
)
@click.option(
    "--workers",
    type=WORKERS,
    default=None,
    help="Worker processes of the local cluster; default the number of CPUs.",
)
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    default=Path("power"),
    show_default=True,
    help="Folder for bank.sqlite, power.json, power.html and power_curves.png/svg.",
)
@click.option("--resume", is_flag=True, help="Continue the bank in --out (only what is missing).")
@click.option(
    "--population",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="With --protocol: a population file (TOML, a [population] table of the model's "
    "fields); default the platform's model.",
)
@click.option(
    "--posthoc-gate",
    type=click.Choice(("auto", "omnibus", "none")),
    default=None,
    help="Which post-hoc families wait for the omnibus test; default the protocol's "
    "[analysis] posthoc_gate (auto: the LSD forms only, Holm and Bonferroni on their own).",
)
def power(
    protocol: str | None,
    from_study: str | None,
    metrics: tuple[str, ...],
    interest: tuple[str, ...],
    model: str,
    draws: int,
    sizes: str,
    studies: int,
    bank: int | None,
    seed: int,
    scheduler: str | None,
    workers: int | None,
    out: Path,
    resume: bool,
    posthoc_gate: str | None,
    population: Path | None,
) -> None:
    """Simulation-based power of every planned test of a protocol: from a bank of
    synthetic participants (--protocol), or from a pilot's own data (--from-study).

    \b
    Examples:
      asa power --from-study pilot.db --studies 1000 --effect-of-interest score_s=20
      asa power --protocol thesis-7-6 --bank 300 --studies 1000 --sizes 6,12,18,24
      asa power --protocol pilot --bank 60 --studies 200 --sizes 6,12 --out pw
      asa power --protocol thesis-7-6 --scheduler tcp://10.0.0.5:8786 --out pw --resume
    """
    import os

    if (protocol is None) == (from_study is None):
        raise ValueError("asa power: give exactly one of --protocol and --from-study")
    workers = workers if workers is not None else (os.cpu_count() or 1)
    if from_study is not None:
        if bank is not None or resume or population is not None:
            raise ValueError("--bank, --resume and --population: only with --protocol (a bank)")
        summary = _from_study(
            from_study, out, sizes, studies, seed, scheduler, workers, posthoc_gate,
            metrics=metrics, interest=interest, model=model, draws=draws,
        )  # fmt: skip
    else:
        if metrics or interest:
            raise ValueError("--metric and --effect-of-interest: only with --from-study")
        summary = _from_bank(
            protocol, out, sizes, studies, bank if bank is not None else 300, seed,
            scheduler, workers, resume, posthoc_gate, population,
        )  # fmt: skip
    for line in summary.lines:
        click.echo(f"  {line}")


def _from_bank(protocol, out, sizes, studies, bank, seed, scheduler, workers, resume, gate, people):
    from study.engine.protocol import load_protocol
    from study.jobs.power import PowerSettings, run_power
    from study.participants.population import Population
    from study.participants.population_file import load_population

    settings = PowerSettings(
        sizes=_sizes(sizes), studies=studies, bank=bank, seed=seed, scheduler=scheduler,
        workers=workers, resume=resume, posthoc_gate=gate,
        population=load_population(people) if people is not None else Population(),
    )  # fmt: skip
    summary = run_power(load_protocol(protocol), out, settings, progress=ProgressBar())
    timing = summary.result["timing"]
    click.echo(
        f"{summary.html} (bank {timing['bank_s']:.0f} s, studies {timing['resample_s']:.0f} s, "
        f"total {timing['total_s']:.0f} s)"
    )
    return summary


def _from_study(source, out, sizes, studies, seed, scheduler, workers, gate, **pilot):
    from study.jobs.power.from_study import FromStudySettings, run_power_from_study

    settings = FromStudySettings(
        sizes=_sizes(sizes), studies=studies, seed=seed, scheduler=scheduler, workers=workers,
        posthoc_gate=gate, metrics=tuple(pilot["metrics"]),
        interest=_interest(pilot["interest"]), model=pilot["model"], draws=pilot["draws"],
    )  # fmt: skip
    summary = run_power_from_study(source, out, settings, progress=ProgressBar())
    timing = summary.result["timing"]
    click.echo(
        f"{summary.html} (studies {timing['simulate_s']:.0f} s, total {timing['total_s']:.0f} s)"
    )
    return summary
