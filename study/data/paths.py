"""Files the platform writes, built only from validated parts under the folder it was
given (issue 20): a name from a scenario, a participant code or a table must be one plain
file name, and the file must stay inside its folder once symbolic links are resolved; an
existing file is replaced only when the user asked for it (``--force``)."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

_BAD_CHARACTERS = ("/", "\\", "\x00")


def check_file_name(name: str, what: str) -> str:
    """``name`` if it is one plain file name (no folder part, not ``.`` or ``..``, no
    ``/``, ``\\`` or NUL), else ``ValueError`` naming ``what`` (e.g. ``"scenario name"``)."""
    if (
        not isinstance(name, str)
        or name in ("", ".", "..")
        or any(c in name for c in _BAD_CHARACTERS)
        or Path(name).is_absolute()
    ):
        raise ValueError(
            f"{what} {name!r} cannot name a file: use letters, digits, '-', '_' and '.', "
            "without a folder part"
        )
    return name


def file_in(folder: str | Path, name: str, suffix: str = "", *, what: str) -> Path:
    """``folder / (name + suffix)``, refused (``ValueError`` naming ``what`` and the
    folder) unless ``name`` is a plain file name and the file, with every symbolic link
    resolved, lies inside ``folder``."""
    folder = Path(folder)
    check_file_name(name, what)
    path = folder / f"{name}{suffix}"
    if not path.resolve().is_relative_to(folder.resolve()):
        raise ValueError(
            f"{path}: {what} {name!r} leads outside {folder} (a symbolic link?); "
            "nothing was written"
        )
    return path


def refuse_existing(paths: Iterable[Path], *, force: bool, field: str = "out") -> None:
    """``ValueError`` naming the first of ``paths`` that exists (or is a dangling link),
    unless ``force``; ``field`` begins the message (``"out: ..."``, turned into the
    command's flag by :func:`study.cli.flag_errors`)."""
    if force:
        return
    for path in paths:
        if path.exists() or path.is_symlink():
            raise ValueError(
                f"{field}: {path} exists already; pass --force to overwrite it "
                "(nothing was written)"
            )


__all__ = ["check_file_name", "file_in", "refuse_existing"]
