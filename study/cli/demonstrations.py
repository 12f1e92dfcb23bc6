"""``asa demonstrations``: record scripted demonstrations of the contextual tasks and
summarise a directory of them.

Thin click commands over :mod:`study.jobs.demonstrations` (``plan_recording``,
``record_demonstrations``, ``summarise``). Bad input (an unknown task or scene, a scene
without a component of the task's kind, a corrupted directory) is a ``ValueError``
naming the option or file, which the ``asa`` shell prints as one line, exit status 2.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import click

from study.cli import COUNT, SEED
from tasks.contextual import DEMONSTRATED, TASK_TYPES, check_task_type


@click.group()
def demonstrations() -> None:
    """Record scripted demonstrations of the contextual tasks, or summarise them."""


@demonstrations.command()
@click.option(
    "--task",
    "task",
    required=True,
    metavar="TYPE",
    help=f"Task type ({', '.join(TASK_TYPES)}) or 'all' for the four demonstrated in the "
    f"thesis ({', '.join(DEMONSTRATED)}), each in its default scene.",
)
@click.option(
    "--scene",
    default=None,
    metavar="NAME",
    help="Scenario name or TOML file (default: the task type's demonstration scene).",
)
@click.option("--runs", type=COUNT, default=12, show_default=True, help="Runs per task type.")
@click.option(
    "--out",
    "out",
    required=True,
    metavar="DIR",
    help="Output directory: DIR/<task>/<scene>_run_<k>.npz and DIR/manifest.json "
    "(merged with an existing manifest).",
)
@click.option("--seed", type=SEED, default=0, show_default=True, help="Master seed.")
def record(task: str, scene: str | None, runs: int, out: str, seed: int) -> None:
    """Drive the simulation with a scripted demonstrator and store the trajectories.

    Each run starts at a random free pose a few metres from a random target of the
    task's kind, with a random direction or side, and stores every tick's poses,
    stick command, target point and task feature (see study.jobs.demonstrations).
    """
    from study.jobs.demonstrations import plan_recording, record_demonstrations, resolve_plan

    if runs < 1:
        raise ValueError(f"--runs: must be at least 1, got {runs}")
    if task != "all":
        check_task_type(task, field="--task")
    plan = resolve_plan(plan_recording(task, scene))  # bad input fails before the bar
    began = time.perf_counter()
    with click.progressbar(length=len(plan) * runs, label="recording", file=sys.stderr) as bar:
        if Path(out).exists() and not Path(out).is_dir():
            raise ValueError(f"{out}: --out must be a directory")
        manifest = record_demonstrations(out, plan, runs, seed=seed, progress=bar.update)
    jobs = {(t, s.name) for t, s in plan}
    written = [r for r in manifest["runs"] if (r["task"], r["scene"]) in jobs and r["run"] < runs]
    done = sum(bool(r["completed"]) for r in written)
    hits = sum(int(r["collisions"]) for r in written)
    click.echo(
        f"wrote {len(written)} runs to {out} in {time.perf_counter() - began:.1f} s: "
        f"{done} completed, {hits} collisions"
    )


@demonstrations.command()
@click.argument("directory", metavar="DIR")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
def show(directory: str, as_json: bool) -> None:
    """Counts per task type: runs, ticks, completion rate, collisions."""
    from study.jobs.demonstrations import summarise

    summary = summarise(directory)
    if as_json:
        click.echo(json.dumps(summary, indent=1))
        return
    click.echo(
        f"{summary['directory']}: {summary['runs']} runs, {summary['ticks']} ticks "
        f"(format {summary['version']}, seed {summary['seed']})"
    )
    header = f"{'task':<20}{'runs':>6}{'ticks':>8}{'moving':>8}{'completed':>11}{'collisions':>12}"
    click.echo(header)
    for name, t in summary["tasks"].items():
        click.echo(
            f"{name:<20}{t['runs']:>6}{t['ticks']:>8}{t['moving_ticks']:>8}"
            f"{t['completion_rate']:>11.0%}{t['collisions']:>12}  {', '.join(t['scenes'])}"
        )
