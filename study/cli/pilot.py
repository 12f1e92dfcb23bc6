"""``asa pilot``: the README's main job (issue 6).

The thesis protocol (``thesis-7-6``) with 18 synthetic participants
(:func:`study.jobs.synth.run_synthetic_study`) into a fresh folder, recordings included; then
the database check (:func:`study.data.dbtools.check`), the report
(:func:`analysis.report.build_report`), where everything is, and the sanity summary
(:func:`study.jobs.synth.sanity_summary`: per mode the completion rate, collisions, score, and
for the contextual mode how often the recognised task and target match the participant's
true intention).

Decisions: the folder is ``pilot-<UTC timestamp>/`` in the current folder unless ``--out``
names one; a folder that exists and is not empty is refused (a pilot never mixes with
earlier data). Inside it: ``pilot.db``, ``pilot_recordings/``, ``report/``. Progress goes
to stderr, the summary to stdout. The command exits 1 when the database check finds
problems (after printing them), like ``asa db check``.
"""

from __future__ import annotations

import datetime as dt
import os
import time
from pathlib import Path

import click


@click.command()
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Folder for the pilot (must be new or empty); default pilot-<timestamp>/ here.",
)
@click.option(
    "--participants",
    type=int,
    default=18,
    show_default=True,
    help="Synthetic participants (the thesis had 18).",
)
@click.option(
    "--workers",
    type=int,
    default=None,
    help="Worker processes; default the number of CPUs.",
)
@click.option("--seed", type=int, default=0, show_default=True, help="The pilot's seed.")
@click.option(
    "--protocol",
    default="thesis-7-6",
    show_default=True,
    help="Shipped protocol name or TOML file.",
)
def pilot(
    out: Path | None, participants: int, workers: int | None, seed: int, protocol: str
) -> None:
    """Run a synthetic pilot study of the thesis protocol and write its report.

    \b
    Example:
      asa pilot                                  # 18 participants, thesis protocol
      asa pilot --participants 6 --out quick/    # a smaller one
    """
    from analysis.report import build_report
    from study.data.dbtools import check
    from study.engine.protocol import load_protocol
    from study.jobs.synth import format_summary, run_synthetic_study, sanity_summary

    start = time.perf_counter()
    p = load_protocol(protocol)
    if out is None:
        stamp = dt.datetime.now(dt.UTC).strftime("%Y%m%d-%H%M%S")
        out = Path(f"pilot-{stamp}")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ValueError(f"--out: {out} exists and is not an empty folder; choose a new one")
    w = workers if workers is not None else (os.cpu_count() or 1)
    out.mkdir(parents=True, exist_ok=True)
    db = out / "pilot.db"

    def say(line: str) -> None:
        click.echo(f"asa pilot: {line}", err=True)

    say(f"{participants} synthetic participants of {p.name} with {w} workers into {out}/")
    summary = run_synthetic_study(
        p, db, participants=participants, seed=seed, workers=w, progress=say
    )
    study_s = summary.wall_s
    say("checking the database")
    report = check(db)
    if not report.clean:
        click.echo(report.text())
    say("writing the report")
    paths = build_report(db, out / "report", progress=say)
    click.echo(f"pilot folder:  {out.resolve()}")
    click.echo(f"database:      {db.resolve()}")
    click.echo(f"recordings:    {(out / 'pilot_recordings').resolve()}")
    click.echo(f"report:        {paths.html.resolve()}")
    click.echo(f"database check: {'clean' if report.clean else 'PROBLEMS (above)'}")
    click.echo(
        f"time: study {study_s:.0f} s, report {paths.seconds:.0f} s, "
        f"total {time.perf_counter() - start:.0f} s"
    )
    click.echo("sanity summary (main trials, per mode):")
    for line in format_summary(sanity_summary(db)):
        click.echo(line)
    if not report.clean:
        raise SystemExit(1)
