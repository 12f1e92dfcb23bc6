"""The ``asa`` command line: one subcommand per job, each a thin shell over a plain
Python function.

Subcommands live in their own modules and are imported only when used, so
``asa --help`` stays fast and a broken optional piece cannot break the others.
To add one, write ``study/cli/<name>.py`` exposing a click command or group
and add a line to ``COMMANDS``.

Bad input anywhere (a malformed file, an unknown name, an impossible option)
is raised as ``ValueError`` (or ``FileNotFoundError``) with the file, field and
what is allowed; :func:`main` turns it, and click's usage errors, into one line
on stderr and exit status 2. Any other exception is a bug and keeps its
traceback. Set ``ASA_DEBUG=1`` to see the traceback of bad input too.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import sys
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

import click

from study import __version__
from study._blas import limit_blas_threads

F = TypeVar("F", bound=Callable[..., Any])

# name -> ("module:attribute", one-line help shown by ``asa --help``)
COMMANDS: dict[str, tuple[str, str]] = {
    "scenario": ("study.cli.scenario:scenario", "Inspect scenarios: components, map, PNG."),
    "bench": ("study.cli.bench:bench", "Measure the performance budgets (one JSON object)."),
    "pilot": ("study.cli.pilot:pilot", "The main job: a synthetic pilot study and its report."),
    "synth": ("study.cli.synth:synth", "A whole study with synthetic participants (workers)."),
    "demonstrations": (
        "study.cli.demonstrations:demonstrations",
        "Record scripted demonstrations of the contextual tasks; summarise them.",
    ),
    "plan": (
        "study.cli.plan:plan_command",
        "Counterbalancing: each participant's mode order and a balance check.",
    ),
    "stats": (
        "study.cli.stats:stats",
        "Repeated-measures ANOVA, sphericity and LSD for any long CSV.",
    ),
    "replay": ("study.cli.replay:replay", "Open a trial's rerun recording, or --print it."),
    "run": ("study.cli.run:run", "One participant's session: a person, scripted or synthetic."),
    "db": ("study.cli.db:db", "Study database tools: check integrity and consistency."),
    "export": ("study.cli.export:export_command", "Write one CSV per database table."),
    "report": (
        "study.cli.report:report_command",
        "The study report: HTML with figures and statistics, tables, results.json.",
    ),
    "train": (
        "study.cli.train:train_command",
        "Learn the contextual-task model from demonstrations (DP-GMM + SOGP).",
    ),
    "evaluate": (
        "study.cli.evaluate:evaluate_command",
        "Cross-validated recognition quality: F0.5, introspection, trajectory rates.",
    ),
}


class LazyGroup(click.Group):
    """A click group whose subcommands are imported on first use."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(COMMANDS)

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        if name not in COMMANDS:
            return None
        target, _ = COMMANDS[name]
        module_name, attribute = target.split(":")
        return getattr(importlib.import_module(module_name), attribute)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        # Help from the table, so `asa --help` imports nothing heavy.
        rows = [(name, COMMANDS[name][1]) for name in self.list_commands(ctx)]
        with formatter.section("Commands"):
            formatter.write_dl(rows)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="asa")
def cli() -> None:
    """asa-study: run and analyse user studies of shared autonomy in mobile-robot
    teleoperation.

    Run `asa COMMAND --help` for the details of each job.
    """


def _one_line(error: BaseException) -> str:
    text = str(error) or error.__class__.__name__
    if isinstance(error, FileNotFoundError) and error.filename:
        text = f"{error.filename}: no such file"
    return " ".join(text.split())


@contextlib.contextmanager
def flag_errors(*parameters: str) -> Iterator[None]:
    """Name the flag in a library ``ValueError`` that names one of ``parameters``.

    The library speaks Python (``"participants: must be ..."``); the command line words
    the same error with its flag (``"--participants: must be ..."``).
    """
    try:
        yield
    except ValueError as error:
        text = str(error)
        for name in parameters:
            if text.startswith(f"{name}: "):
                flag = "--" + name.replace("_", "-")
                raise ValueError(flag + text[len(name) :]) from error
        raise


def db_option(help: str, *, name: str = "db") -> Callable[[F], F]:
    """The ``--db`` option: a file path or a SQLAlchemy URL, passed on as written.

    A plain string, not ``click.Path``: a path type would normalise
    ``postgresql://host/db`` into ``postgresql:/host/db`` (docs/decisions.md).
    """
    return click.option("--db", name, required=True, type=str, metavar="PATH|URL", help=help)


def main(argv: list[str] | None = None) -> None:
    """Entry point of the ``asa`` console script."""
    debug = os.environ.get("ASA_DEBUG") == "1"
    try:
        limit_blas_threads()
        cli.main(args=argv, prog_name="asa", standalone_mode=False)
    except click.exceptions.Abort:
        click.echo("asa: aborted", err=True)
        sys.exit(130)
    except click.ClickException as error:
        # Bad options or arguments: click's own message, on one line.
        click.echo(f"asa: {' '.join(error.format_message().split())}", err=True)
        sys.exit(2)
    except (ValueError, FileNotFoundError) as error:
        # Bad input, named by the library; any other exception is a bug: a traceback.
        if debug:
            raise
        click.echo(f"asa: error: {_one_line(error)}", err=True)
        sys.exit(2)
    except KeyboardInterrupt:
        click.echo("asa: interrupted", err=True)
        sys.exit(130)
