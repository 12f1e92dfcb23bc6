"""A throwaway PostgreSQL server for the postgres tests and the storage benchmark (issue 24).

Debian's PostgreSQL binaries (``apt-get install postgresql``; ``initdb`` and ``pg_ctl``
from ``pg_config --bindir`` or ``/usr/lib/postgresql/<version>/bin``) make a cluster in a
temporary folder, listening on a free port of 127.0.0.1 only (its unix socket inside the
folder), with trust authentication for the database user ``asa``. The Debian package's
own cluster service is not used. ``initdb`` refuses to run as root: as root the server
runs as the system user ``postgres`` (made by the Debian package), else as ``asa-pg``,
created with ``useradd --system`` when missing. Missing binaries are an error, never a
skip: CI installs them (.ci/run).
"""

from __future__ import annotations

import contextlib
import glob
import itertools
import os
import pwd
import shutil
import socket
import subprocess
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

DB_USER = "asa"  # the cluster's superuser, trusted on 127.0.0.1
START_TIMEOUT_S = 60


def bin_folder() -> Path:
    """The folder of ``initdb`` and ``pg_ctl`` (the newest Debian version), or a
    ``RuntimeError`` saying how to install them."""
    candidates = []
    with contextlib.suppress(OSError, subprocess.CalledProcessError):
        out = subprocess.run(
            ["pg_config", "--bindir"], capture_output=True, text=True, check=True
        ).stdout
        candidates.append(Path(out.strip()))
    found = sorted(glob.glob("/usr/lib/postgresql/*/bin"), key=_version, reverse=True)
    candidates += [Path(p) for p in found]
    for folder in candidates:
        if (folder / "initdb").is_file() and (folder / "pg_ctl").is_file():
            return folder
    raise RuntimeError(
        "the tests marked 'postgres' need PostgreSQL's server binaries (initdb, pg_ctl), "
        "found neither by `pg_config --bindir` nor in /usr/lib/postgresql/*/bin; install "
        "them with `apt-get install postgresql` (.ci/run does)"
    )


def _version(path: str) -> int:
    part = Path(path).parent.name
    return int(part) if part.isdigit() else 0


def _server_user() -> str | None:
    """The user the server runs as: None (this one) unless root, else ``postgres`` or
    ``asa-pg`` (created if missing)."""
    if os.geteuid() != 0:
        return None
    for name in ("postgres", "asa-pg"):
        with contextlib.suppress(KeyError):
            pwd.getpwnam(name)
            return name
    subprocess.run(
        ["useradd", "--system", "--no-create-home", "--shell", "/usr/sbin/nologin", "asa-pg"],
        check=True,
        capture_output=True,
    )
    return "asa-pg"


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class Server:
    """A running server: its folder, port and the ``as`` prefix that runs its tools."""

    folder: Path
    port: int
    bindir: Path
    prefix: list[str]
    _numbers: Iterator[int] = field(default_factory=lambda: itertools.count(1))

    def url(self, database: str) -> str:
        return f"postgresql+psycopg://{DB_USER}@127.0.0.1:{self.port}/{database}"

    def new_database(self) -> str:
        """A fresh database ``t_<n>``; its URL."""
        import psycopg

        name = f"t_{next(self._numbers)}"
        dsn = f"host=127.0.0.1 port={self.port} user={DB_USER} dbname=postgres"
        with psycopg.connect(dsn, autocommit=True) as conn:
            conn.execute(f'CREATE DATABASE "{name}"')
        return self.url(name)

    def stop(self) -> None:
        self._run("pg_ctl", "stop", "-D", str(self.folder / "data"), "-m", "fast", "-w")

    def _run(self, tool: str, *args: str) -> None:
        done = subprocess.run(
            [*self.prefix, str(self.bindir / tool), *args],
            capture_output=True,
            text=True,
            timeout=START_TIMEOUT_S,
        )
        if done.returncode != 0:
            log = self.folder / "server.log"
            tail = log.read_text()[-2000:] if log.is_file() else ""
            raise RuntimeError(f"{tool} {' '.join(args)} failed:\n{done.stderr}\n{tail}")


def start() -> Server:
    """Make a cluster in a new temporary folder and start it on a free port."""
    bindir = bin_folder()
    user = _server_user()
    folder = Path(tempfile.mkdtemp(prefix="asa-pg-"))
    prefix = [] if user is None else ["runuser", "-u", user, "--"]
    if user is not None:
        shutil.chown(folder, user)
    server = Server(folder, _free_port(), bindir, prefix)
    try:
        server._run(
            "initdb", "-D", str(folder / "data"), "-U", DB_USER, "--auth=trust",
            "-E", "UTF8", "--locale=C", "--no-sync",
        )  # fmt: skip
        options = (
            f"-c listen_addresses=127.0.0.1 -p {server.port} -k {folder} "
            "-c fsync=off -c synchronous_commit=off -c full_page_writes=off"
        )
        server._run(
            "pg_ctl", "start", "-D", str(folder / "data"), "-w", "-t", str(START_TIMEOUT_S),
            "-l", str(folder / "server.log"), "-o", options,
        )  # fmt: skip
    except BaseException:
        shutil.rmtree(folder, ignore_errors=True)
        raise
    return server


@contextlib.contextmanager
def running() -> Iterator[Server]:
    """A server for the block; stopped and its folder removed afterwards."""
    server = start()
    try:
        yield server
    finally:
        try:
            server.stop()
        finally:
            shutil.rmtree(server.folder, ignore_errors=True)
