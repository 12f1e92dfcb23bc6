"""The model file a trial's mode read, named by its file name and SHA-256 (issue 40): the
trial outcome stores them so that the Methods can name the model without the absolute
path of the machine that ran the study."""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path
from typing import Any

_CHUNK = 1 << 20  # [bytes] read at a time


@functools.lru_cache(maxsize=16)
def _sha256(path: str, mtime_ns: int, size: int) -> str:
    """The SHA-256 of the file ``path`` as of ``mtime_ns`` and ``size`` (the cache key: a
    model file rewritten in place is hashed again)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(_CHUNK):
            h.update(chunk)
    return h.hexdigest()


def model_identity(mode_settings: dict[str, Any] | None) -> dict[str, str] | None:
    """``{"file": name, "sha256": hex}`` of the file in the settings' ``model_path``, hashed
    once per file and version; None without a ``model_path`` or when it names no file
    (a mode without a model: the outcome then names none)."""
    if not mode_settings or not isinstance(mode_settings.get("model_path"), str):
        return None
    path = Path(mode_settings["model_path"])
    if not mode_settings["model_path"] or not path.is_file():
        return None
    stat = path.stat()
    return {
        "file": path.name,
        "sha256": _sha256(str(path.resolve()), stat.st_mtime_ns, stat.st_size),
    }
