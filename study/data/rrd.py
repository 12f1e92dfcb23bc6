"""Trial recordings after the trial: read back, verified with ``rerun rrd verify``, opened
in the rerun viewer (``asa replay``, ``asa db check``)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from rerun.chunk import RrdReader

from study.data.recording import TIMELINE

# rerun's analytics are off in every rerun process the platform starts (docs/decisions.md).
ANALYTICS_OFF_ENV: dict[str, str] = {"CI": "1"}
VIEWER_BIND = "127.0.0.1"  # the replay viewer's gRPC server listens on localhost only
VIEWER_GRACE_S = 2.0  # [s] a viewer that fails (no display, no GPU) does so within this
_ANSI = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")


def rerun_environment() -> dict[str, str]:
    """``os.environ`` plus :data:`ANALYTICS_OFF_ENV`: the environment of every rerun process."""
    return {**os.environ, **ANALYTICS_OFF_ENV}


def rerun_executable() -> str:
    """Path of the ``rerun`` executable shipped with rerun-sdk.

    The binary itself, not ``python -m rerun_cli`` (that wrapper drops the exit status).
    """
    import rerun_cli

    bundled = Path(rerun_cli.__file__).with_name("rerun.exe" if os.name == "nt" else "rerun")
    if bundled.is_file():
        return str(bundled)
    found = shutil.which("rerun")
    if found is None:
        raise FileNotFoundError(2, "the rerun executable (rerun-sdk) was not found", "rerun")
    return found


def _duration_ns(column: Any) -> np.ndarray:
    import pyarrow as pa

    return np.asarray(column.cast(pa.int64()).to_numpy(zero_copy_only=False), dtype=np.int64)


def recording_summary(path: str | Path) -> dict[str, Any]:
    """What an ``.rrd`` file holds, read back with the rerun SDK.

    Parameters
    ----------
    path : str or Path
        The recording.

    Returns
    -------
    dict
        ``path``; ``application_id`` and ``recording_id``; ``entities``: entity
        path (without the leading ``/``) -> ``{"rows": temporal rows, "static":
        static rows}``, sorted by path, rerun's own ``__`` entities left out;
        ``timeline``: ``"sim_time"``; ``time_range_s``: ``[first, last]`` [s] over
        all temporal rows, or ``None`` if there are none.

    Raises
    ------
    ValueError
        When the file is not a readable rerun recording (names the file).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(2, "No such file", str(path))
    try:
        reader = RrdReader(path)
        stores = reader.recordings()
        chunks = reader.stream().to_chunks() if stores else []
    except (RuntimeError, OSError, ValueError) as error:
        raise ValueError(f"{path}: not a readable rerun recording ({error})") from None
    if not stores:
        raise ValueError(f"{path}: holds no rerun recording")
    entities: dict[str, dict[str, int]] = {}
    lo, hi = None, None
    for chunk in chunks:
        name = chunk.entity_path.lstrip("/")
        if name.startswith("__") or chunk.is_empty:
            continue
        counts = entities.setdefault(name, {"rows": 0, "static": 0})
        if chunk.is_static:
            counts["static"] += chunk.num_rows
            continue
        counts["rows"] += chunk.num_rows
        if TIMELINE in chunk.timeline_names:
            ns = _duration_ns(chunk.to_record_batch().column(TIMELINE))
            lo = int(ns.min()) if lo is None else min(lo, int(ns.min()))
            hi = int(ns.max()) if hi is None else max(hi, int(ns.max()))
    return {
        "path": str(path),
        "application_id": stores[0].application_id,
        "recording_id": stores[0].recording_id,
        "entities": dict(sorted(entities.items())),
        "timeline": TIMELINE,
        "time_range_s": None if lo is None else [lo / 1e9, hi / 1e9],
    }


def format_summary(summary: Mapping[str, Any]) -> str:
    """:func:`recording_summary` as readable lines (``asa replay --print``)."""
    lines = [
        f"recording {summary['path']}",
        f"  application {summary['application_id']}, recording id {summary['recording_id']}",
    ]
    span = summary["time_range_s"]
    if span is None:
        lines.append(f"  timeline {summary['timeline']}: no temporal data")
    else:
        lines.append(f"  timeline {summary['timeline']}: {span[0]:.3f} s .. {span[1]:.3f} s")
    width = max((len(name) for name in summary["entities"]), default=10)
    lines.append(f"  {'entity'.ljust(width)}  {'rows':>7}  {'static':>6}")
    for name, counts in summary["entities"].items():
        lines.append(f"  {name.ljust(width)}  {counts['rows']:>7}  {counts['static']:>6}")
    frames = [
        f"{name} {counts['rows']}"
        for name, counts in summary["entities"].items()
        if name.startswith("camera/") and counts["rows"]
    ]
    lines.append(f"  camera frames: {', '.join(frames) if frames else 'none'}")
    return "\n".join(lines)


def verify(path: str | Path, *, timeout_s: float = 120.0) -> None:
    """Check a recording with ``rerun rrd verify`` (footers included).

    ``rerun rrd verify`` reports success for a file that is no recording at all
    ("0 files verified"), so the file must also open with the SDK's reader and
    hold a recording.

    Raises
    ------
    ValueError
        Naming the file, with rerun's message, when verification fails.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(2, "No such file", str(path))
    try:
        done = subprocess.run(
            [rerun_executable(), "rrd", "verify", "--check-footers", "true", str(path)],
            capture_output=True,
            text=True,
            env=rerun_environment(),
            timeout=timeout_s,
            check=False,
        )
    except subprocess.TimeoutExpired:
        raise ValueError(f"{path}: rerun rrd verify took longer than {timeout_s} s") from None
    if done.returncode != 0:
        message = " ".join((done.stderr or done.stdout).split()) or f"exit {done.returncode}"
        raise ValueError(f"{path}: rerun rrd verify failed: {message}")
    recording_summary(path)  # raises ValueError if it is no recording


def verify_many(paths: list[Path], *, timeout_s: float = 600.0) -> dict[Path, str]:
    """Check many recordings with one ``rerun rrd verify`` (a process start per file costs
    about 0.1 s); returns path -> error message for the files that fail (empty: all good).

    Only when the batch fails, or verifies fewer files than it was given (a file that is no
    recording at all is skipped silently by rerun), is every file checked by :func:`verify`
    on its own to name the culprits.
    """
    paths = [Path(p) for p in paths]
    missing = {p: "No such file" for p in paths if not p.is_file()}
    present = [p for p in paths if p not in missing]
    if not present:
        return missing
    try:
        done = subprocess.run(
            [rerun_executable(), "rrd", "verify", "--check-footers", "true", *map(str, present)],
            capture_output=True,
            text=True,
            env=rerun_environment(),
            timeout=timeout_s,
            check=False,
        )
        text = f"{done.stdout}\n{done.stderr}"
        counted = re.search(r"(\d+) files? verified without error", text)
        ok = done.returncode == 0 and counted is not None and int(counted[1]) == len(present)
    except subprocess.TimeoutExpired:
        ok = False
    if ok:
        return missing
    failures = dict(missing)
    for path in present:
        try:
            verify(path)
        except (ValueError, FileNotFoundError) as error:
            failures[path] = " ".join(str(error).split())
    return failures


def viewer_command(path: str | Path) -> list[str]:
    """The command that opens the rerun viewer on ``path`` (run it with
    :func:`rerun_environment`): its gRPC server bound to :data:`VIEWER_BIND` (rerun's
    default is every interface, 0.0.0.0) on a free port (``--new``: never handed to
    whatever listens on rerun's default port)."""
    return [rerun_executable(), "--bind", VIEWER_BIND, "--new", str(path)]


def has_display() -> bool:
    """Whether a window can be opened: on Linux and the BSDs ``DISPLAY`` or a Wayland
    variable is set; elsewhere assumed."""
    if not sys.platform.startswith(("linux", "freebsd", "openbsd", "netbsd")):
        return True
    return any(os.environ.get(v) for v in ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET"))


def open_viewer(path: str | Path, *, grace_s: float = VIEWER_GRACE_S) -> subprocess.Popen[bytes]:
    """Start the rerun viewer on ``path`` in its own process, bound to localhost.

    Waits up to ``grace_s`` [s] for it to fail; a viewer still running then is returned
    (its ``returncode`` None), as is one that ended cleanly within it.

    Raises
    ------
    ValueError
        One line naming the recording: no display to open a window on, or the viewer
        ended with an error within ``grace_s`` (with rerun's own error line).
    """
    if not has_display():
        raise ValueError(
            f"{path}: cannot open the rerun viewer: no display (DISPLAY and WAYLAND_DISPLAY "
            "are not set); `asa replay --print` shows what the recording holds"
        )
    with tempfile.TemporaryFile() as log:  # the viewer keeps its copy of the descriptor
        process = subprocess.Popen(
            viewer_command(path),
            env=rerun_environment(),
            stdin=subprocess.DEVNULL,
            stdout=log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        try:
            code = process.wait(timeout=grace_s)
        except subprocess.TimeoutExpired:
            return process
        if code == 0:
            return process
        log.seek(0)
        reason = _viewer_error(log.read().decode("utf-8", "replace")) or f"exit status {code}"
    raise ValueError(
        f"{path}: the rerun viewer did not start ({reason}); `asa replay --print` shows what "
        "the recording holds"
    )


def _viewer_error(output: str) -> str:
    """rerun's error line from its output (ANSI colours removed), else its last line."""
    lines = [" ".join(_ANSI.sub("", line).split()) for line in output.splitlines()]
    lines = [line for line in lines if line]
    errors = [line for line in lines if line.startswith("Error")]
    return (errors or lines or [""])[-1][:300]


__all__ = [
    "ANALYTICS_OFF_ENV",
    "VIEWER_BIND",
    "format_summary",
    "has_display",
    "open_viewer",
    "recording_summary",
    "rerun_environment",
    "rerun_executable",
    "verify",
    "verify_many",
    "viewer_command",
]
