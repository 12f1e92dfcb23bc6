"""The ``asa`` command line: one subcommand per job, each a thin shell over a plain
Python function.

Subcommands live in their own modules and are imported only when used, so
``asa --help`` stays fast and a broken optional piece cannot break the others.
To add one, write ``study/cli/<name>.py`` exposing a click command or group
and add a line to ``COMMANDS``.

Bad input anywhere (a malformed file, an unknown name, an impossible option)
is raised as ``ValueError`` (or ``FileNotFoundError``) with the file, field and
what is allowed; :func:`main` turns it, and click's usage errors, into one line
on stderr and exit status 2. So does a failing disk or file system (full, read-only,
no permission, an I/O error; also SQLite's "database or disk is full"), naming the file:
``asa: error: <file>: no space left on device``. Any other exception is a bug and keeps
its traceback. Set ``ASA_DEBUG=1`` to see the traceback of bad input too.
"""

from __future__ import annotations

import contextlib
import errno
import importlib
import io
import os
import sqlite3
import sys
import traceback
from collections.abc import Callable, Iterator, Sequence
from typing import Any, TypeVar

import click

from sim.limits import MAX_COUNT, MAX_PARTICIPANTS, MAX_SEED
from study import __version__
from study._blas import limit_blas_threads

F = TypeVar("F", bound=Callable[..., Any])
# Option types with the platform's bounds (sim.limits), shared by the subcommands.
SEED = click.IntRange(0, MAX_SEED)  # stored in SQLite's signed 64-bit integer
PARTICIPANTS = click.IntRange(1, MAX_PARTICIPANTS)
WORKERS = click.IntRange(1, 1024)
COUNT = click.IntRange(1, MAX_COUNT)
ROW_ID = click.IntRange(1, MAX_SEED)

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
    "power": (
        "study.cli.power:power",
        "How many participants each planned test needs: simulated on Dask.",
    ),
    "calibrate": (
        "study.cli.calibrate:calibrate",
        "Fit the synthetic population to a study's people (a population file).",
    ),
    "stats": (
        "study.cli.stats:stats",
        "Repeated-measures ANOVA, sphericity and LSD for any long CSV.",
    ),
    "replay": ("study.cli.replay:replay", "Open a trial's rerun recording, or --print it."),
    "run": ("study.cli.run:run", "One participant's session: a person, scripted or synthetic."),
    "serve": (
        "study.cli.serve:serve",
        "Run the protocol's sessions for participants who join from a browser link.",
    ),
    "invite": ("study.cli.serve:invite", "Make browser links for participants of `asa serve`."),
    "snapshots": (
        "study.cli.serve:snapshots",
        "Screenshots of every screen of a protocol in headless Chromium.",
    ),
    "db": (
        "study.cli.db:db",
        "Study database tools: check, diff, upgrade, push a site's database.",
    ),
    "export": (
        "study.cli.export:export_command",
        "Write one CSV per database table (--aligned: the lab's streams on one clock).",
    ),
    "xdf": (
        "study.cli.xdf:xdf",
        "LabRecorder's XDF files: import one, aligned with the trials by the markers.",
    ),
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


# errno values of a failing disk or file system, not of a bug
_IO_ERRNOS = frozenset(
    getattr(errno, name)
    for name in (
        "ENOSPC", "EDQUOT", "EIO", "EACCES", "EPERM", "EROFS", "EFBIG", "ENOTDIR",
        "EISDIR", "ENAMETOOLONG", "ENXIO", "ENODEV", "ELOOP", "EMFILE", "ENFILE", "EBUSY",
        "ETXTBSY", "ESTALE",
    )
    if hasattr(errno, name)
)  # fmt: skip
# SQLite's messages for the same (sqlite3.OperationalError, often wrapped by SQLAlchemy)
_SQLITE_IO = (
    "database or disk is full",
    "disk i/o error",
    "attempt to write a readonly database",
    "unable to open database file",
)


def _chain(error: BaseException) -> list[BaseException]:
    """``error`` and the exceptions it was raised from or while handling, outermost first."""
    out: list[BaseException] = []
    current: BaseException | None = error
    while current is not None and all(current is not e for e in out):
        out.append(current)
        current = current.__cause__ or current.__context__
    return out


def _frames_locals(chain: Sequence[BaseException]) -> Iterator[object]:
    """The local values of every frame of the chain's tracebacks, innermost frame first."""
    for error in chain:
        frames = [frame for frame, _ in traceback.walk_tb(error.__traceback__)]
        for frame in reversed(frames):
            yield from list(frame.f_locals.values())


def _database_name(chain: Sequence[BaseException], argv: Sequence[str]) -> str:
    """The SQLite file a failing statement wrote to: from a SQLAlchemy engine or connection
    in the traceback, else ``--db``, else "the study database"."""
    try:
        from sqlalchemy.engine import Connection, Engine
    except ImportError:  # pragma: no cover - SQLAlchemy is a dependency
        Connection = Engine = ()  # type: ignore[assignment,misc]  # noqa: N806
    for value in _frames_locals(chain):
        if isinstance(value, Connection | Engine):
            engine = value.engine if isinstance(value, Connection) else value
            if engine.url.database:
                return str(engine.url.database)
    for i, arg in enumerate(argv):
        if arg == "--db" and i + 1 < len(argv):
            return argv[i + 1]
        if arg.startswith("--db="):
            return arg[len("--db=") :]
    return "the study database"


def _file_name(error: OSError, chain: Sequence[BaseException]) -> str | None:
    """The file an ``OSError`` concerns: its ``filename``, else an open file in the
    innermost frames of the traceback (a failing ``write`` names no file)."""
    if error.filename is not None:
        return os.fsdecode(error.filename)
    for value in _frames_locals(chain):
        if isinstance(value, io.IOBase) and isinstance(getattr(value, "name", None), str):
            return value.name
    return None


def io_error_line(error: BaseException, argv: Sequence[str] = ()) -> str | None:
    """One line for a failing disk or file system anywhere in ``error``'s chain, naming the
    file (``"<file>: no space left on device"``), or ``None`` when it is something else."""
    chain = _chain(error)
    for e in chain:
        if isinstance(e, OSError) and e.errno in _IO_ERRNOS:
            what = (e.strerror or errno.errorcode.get(e.errno or 0, "I/O error")).lower()
            name = _file_name(e, chain)
            return f"{name}: {what}" if name else f"{what} (errno {e.errno})"
        orig = getattr(e, "orig", None)  # SQLAlchemy's DBAPIError wraps sqlite3's error
        for candidate in (e, orig):
            if isinstance(candidate, sqlite3.OperationalError):
                text = " ".join(str(candidate).split())
                if any(s in text.lower() for s in _SQLITE_IO):
                    return f"{_database_name(chain, argv)}: {text}"
    return None


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
    except Exception as error:
        # A full disk, a read-only file system ...: one line naming the file. Else a bug.
        line = None if debug else io_error_line(error, sys.argv[1:] if argv is None else argv)
        if line is None:
            raise
        click.echo(f"asa: error: {line}", err=True)
        sys.exit(2)
