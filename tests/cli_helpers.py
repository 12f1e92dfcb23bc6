"""Running the ``asa`` command line inside the test process (faster than a subprocess;
what a user sees is the same: stdout, stderr and the exit status)."""

from __future__ import annotations

import pytest

from study.cli import main


def asa(capsys: pytest.CaptureFixture[str], *args: object) -> tuple[int, str, str]:
    """Run ``asa ARGS`` in this process: (exit status, stdout, stderr) of this command
    alone (what was captured before is dropped). The status follows Python's
    ``SystemExit``: None is 0, an integer itself, anything else 1."""
    capsys.readouterr()
    code = 0
    try:
        main([str(a) for a in args])
    except SystemExit as stop:
        code = stop.code if isinstance(stop.code, int) else (0 if stop.code is None else 1)
    out = capsys.readouterr()
    return code, out.out, out.err
