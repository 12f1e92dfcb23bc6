"""The demonstrations' files: one ``.npz`` per run and ``manifest.json`` (format 1), and
loading a directory back with every file checked against the manifest (spec section 3).
"""

from __future__ import annotations

import hashlib
import io
import json
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from tasks.contextual import TASK_TYPES

FORMAT_VERSION = 1
MANIFEST = "manifest.json"

# name -> (dtype kind, trailing shape); "n" ticks, "m" candidate points in total
_ARRAYS: dict[str, tuple[str, tuple[int, ...]]] = {
    "t": ("f", ()),
    "pose_true": ("f", (3,)),
    "pose_est": ("f", (3,)),
    "u": ("f", (3,)),
    "u_norm": ("f", (3,)),
    "target": ("U", ()),  # id of the demonstrated component
    "s": ("f", (2,)),
    "q": ("f", (6,)),
    "moving": ("b", ()),
    "phase": ("U", ()),
    "cand_offsets": ("i", ()),  # (n + 1,)
    "cand_points": ("f", (2,)),  # (m, 2)
    "cand_ids": ("U", ()),  # (m,)
    "cand_kinds": ("U", ()),  # (m,)
}
_RUN_FIELDS = (
    "file",
    "scene",
    "task",
    "direction",
    "target",
    "ticks",
    "completed",
    "collisions",
    "sha256",
)


@dataclass(frozen=True, slots=True)
class Demonstrations:
    """Demonstrations loaded from a directory; n ticks, m candidate points in total.

    ``task`` is the true task type, for evaluation only.
    """

    q: np.ndarray  # (n, 6) task features against the demonstrated target
    s: np.ndarray  # (n, 2) [m] demonstrated target point, robot frame
    u: np.ndarray  # (n, 3) stick command [m/s, m/s, rad/s]
    u_norm: np.ndarray  # (n, 3) the same in (-1, 1) units
    t: np.ndarray  # (n,) [s] time since the run's start
    pose_true: np.ndarray  # (n, 3) [m, m, rad] map frame
    pose_est: np.ndarray  # (n, 3) [m, m, rad] map frame
    run: np.ndarray  # (n,) int index into ``runs``
    task: np.ndarray  # (n,) str true task type (evaluation only)
    target: np.ndarray  # (n,) str id of the demonstrated component
    phase: np.ndarray  # (n,) str the demonstrator's phase: "approach", then the task's own
    cand_offsets: np.ndarray  # (n + 1,) int: tick i's candidates are [off[i], off[i+1])
    cand_points: np.ndarray  # (m, 2) [m] target points of all candidates, robot frame
    cand_ids: np.ndarray  # (m,) str
    cand_kinds: np.ndarray  # (m,) str
    runs: tuple[dict[str, Any], ...]  # the manifest's run entries
    directory: str

    def candidates(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Ids (k,) and target points (k, 2) [m] of tick ``i``'s candidates."""
        a, b = int(self.cand_offsets[i]), int(self.cand_offsets[i + 1])
        return self.cand_ids[a:b], self.cand_points[a:b]

    def __len__(self) -> int:
        return len(self.q)


def _npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    """An .npz archive with fixed timestamps (np.savez stamps the current time)."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name in sorted(arrays):
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            data = io.BytesIO()
            np.lib.format.write_array(data, np.ascontiguousarray(arrays[name]), allow_pickle=False)
            archive.writestr(info, data.getvalue())
    return buffer.getvalue()


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _read_manifest(directory: Path) -> dict[str, Any]:
    path = directory / MANIFEST
    if not directory.is_dir():
        raise ValueError(f"{directory}: not a directory of demonstrations")
    if not path.is_file():
        raise ValueError(f"{path}: no manifest (record with `asa demonstrations record`)")
    try:
        manifest = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"{path}: not a readable JSON manifest ({error})") from None
    if not isinstance(manifest, dict):
        raise ValueError(f"{path}: the manifest must be a JSON object")
    if manifest.get("version") != FORMAT_VERSION:
        raise ValueError(
            f"{path}: field 'version': {manifest.get('version')!r} not supported "
            f"(this platform reads {FORMAT_VERSION})"
        )
    runs = manifest.get("runs")
    if not isinstance(runs, list):
        raise ValueError(f"{path}: field 'runs': must be a list of run entries")
    for i, entry in enumerate(runs):
        if not isinstance(entry, dict):
            raise ValueError(f"{path}: field 'runs[{i}]': must be an object")
        for name in _RUN_FIELDS:
            if name not in entry:
                raise ValueError(f"{path}: field 'runs[{i}].{name}': missing")
        if entry["task"] not in TASK_TYPES:
            raise ValueError(
                f"{path}: field 'runs[{i}].task': {entry['task']!r} unknown; "
                f"allowed: {', '.join(TASK_TYPES)}"
            )
        rel = Path(str(entry["file"]))
        if rel.is_absolute() or ".." in rel.parts:
            raise ValueError(f"{path}: field 'runs[{i}].file': must be a path inside {directory}")
    return manifest


def _load_run(path: Path, entry: dict[str, Any]) -> dict[str, np.ndarray]:
    if not path.is_file():
        raise ValueError(f"{path}: missing (listed in the manifest)")
    digest = _sha256(path)
    if digest != entry["sha256"]:
        raise ValueError(
            f"{path}: field 'sha256': file hash {digest[:12]}... does not match the "
            f"manifest's {str(entry['sha256'])[:12]}... (file changed or corrupted)"
        )
    try:
        # our own handle: np.load leaves its file open when the archive is corrupt
        with open(path, "rb") as handle, np.load(handle, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    except Exception as error:  # zipfile, format or pickle errors all mean a bad file
        raise ValueError(f"{path}: not a readable .npz file ({error})") from None
    for name in _ARRAYS:
        if name not in arrays:
            raise ValueError(f"{path}: field '{name}': missing array")
    n = len(arrays["t"])
    m = len(arrays["cand_points"])
    for name, (kind, trailing) in _ARRAYS.items():
        a = arrays[name]
        rows = n + 1 if name == "cand_offsets" else m if name.startswith("cand_") else n
        if a.shape != (rows, *trailing) or a.dtype.kind not in (kind, "u" if kind == "i" else kind):
            raise ValueError(
                f"{path}: field '{name}': expected shape {(rows, *trailing)} of kind "
                f"'{kind}', got {a.shape} {a.dtype}"
            )
        if kind == "f" and not np.all(np.isfinite(a)):
            raise ValueError(f"{path}: field '{name}': must be finite")
    off = arrays["cand_offsets"]
    if off[0] != 0 or off[-1] != m or np.any(np.diff(off) < 0):
        raise ValueError(
            f"{path}: field 'cand_offsets': must rise from 0 to {m} (the candidate count)"
        )
    if n and not np.all(arrays["target"] == entry["target"]):
        raise ValueError(
            f"{path}: field 'target': does not match the manifest's {entry['target']!r}"
        )
    if n != entry["ticks"]:
        raise ValueError(
            f"{path}: field 'ticks': manifest says {entry['ticks']}, file has {n} ticks"
        )
    return arrays


def load_demonstrations(directory: str | Path, *, moving_only: bool = True) -> Demonstrations:
    """Load and validate a directory of demonstrations.

    Parameters
    ----------
    directory : path
        A directory written by :func:`record_demonstrations` (``asa demonstrations record``).
    moving_only : bool
        Keep only ticks with translational input (the way points; docs/decisions.md).

    Returns
    -------
    Demonstrations
        All runs concatenated in manifest order.

    Raises
    ------
    ValueError
        Naming the file and field: missing manifest, missing file, hash mismatch,
        unreadable file, missing array, wrong shape.
    """
    directory = Path(directory)
    manifest = _read_manifest(directory)
    parts: dict[str, list[np.ndarray]] = {name: [] for name in (*_ARRAYS, "run", "task")}
    offset_base = 0
    for i, entry in enumerate(manifest["runs"]):
        a = _load_run(directory / entry["file"], entry)
        keep = a["moving"] if moving_only else np.ones(len(a["t"]), dtype=bool)
        offset_base = _append_run(parts, a, keep, offset_base)
        k = int(np.count_nonzero(keep))
        parts["run"].append(np.full(k, i, dtype=np.int64))
        parts["task"].append(np.full(k, entry["task"]))

    def cat(name: str, shape: tuple[int, ...], dtype: Any) -> np.ndarray:
        return np.concatenate(parts[name]) if parts[name] else np.zeros(shape, dtype=dtype)

    offsets = np.concatenate(([0], cat("cand_offsets", (0,), np.int64))).astype(np.int64)
    return Demonstrations(
        q=cat("q", (0, 6), float),
        s=cat("s", (0, 2), float),
        u=cat("u", (0, 3), float),
        u_norm=cat("u_norm", (0, 3), float),
        t=cat("t", (0,), float),
        pose_true=cat("pose_true", (0, 3), float),
        pose_est=cat("pose_est", (0, 3), float),
        run=cat("run", (0,), np.int64),
        task=cat("task", (0,), str),
        target=cat("target", (0,), str),
        phase=cat("phase", (0,), str),
        cand_offsets=offsets,
        cand_points=cat("cand_points", (0, 2), float),
        cand_ids=cat("cand_ids", (0,), str),
        cand_kinds=cat("cand_kinds", (0,), str),
        runs=tuple(manifest["runs"]),
        directory=str(directory),
    )


def _append_run(
    parts: dict[str, list[np.ndarray]], a: dict[str, np.ndarray], keep: np.ndarray, base: int
) -> int:
    """Append the kept ticks (n,) bool of run ``a`` and their candidates to ``parts``; the
    candidate offsets continue from ``base``. Returns the next base."""
    off = a["cand_offsets"]
    idx = np.nonzero(keep)[0]
    counts = off[idx + 1] - off[idx]
    picks = (
        np.concatenate([np.arange(off[j], off[j + 1]) for j in idx])
        if len(idx)
        else np.zeros(0, dtype=int)
    )
    for name in _ARRAYS:
        if name == "cand_offsets":
            continue
        parts[name].append(a[name][picks] if name.startswith("cand_") else a[name][keep])
    parts["cand_offsets"].append(base + np.cumsum(counts))
    return base + int(counts.sum())


def summarise(directory: str | Path) -> dict[str, Any]:
    """Counts per task type from the manifest (files are checked by hash too).

    Returns
    -------
    dict
        ``{"directory", "runs", "ticks", "tasks": {task: {"runs", "ticks",
        "moving_ticks", "completed", "completion_rate", "collisions", "scenes"}}}``.
    """
    directory = Path(directory)
    manifest = _read_manifest(directory)
    tasks: dict[str, dict[str, Any]] = {}
    for entry in manifest["runs"]:
        path = directory / entry["file"]
        if not path.is_file():
            raise ValueError(f"{path}: missing (listed in the manifest)")
        if _sha256(path) != entry["sha256"]:
            raise ValueError(f"{path}: field 'sha256': does not match the manifest")
        t = tasks.setdefault(
            entry["task"],
            {
                "runs": 0,
                "ticks": 0,
                "moving_ticks": 0,
                "completed": 0,
                "collisions": 0,
                "scenes": [],
            },
        )
        t["runs"] += 1
        t["ticks"] += int(entry["ticks"])
        t["moving_ticks"] += int(entry.get("moving_ticks", entry["ticks"]))
        t["completed"] += int(bool(entry["completed"]))
        t["collisions"] += int(entry["collisions"])
        if entry["scene"] not in t["scenes"]:
            t["scenes"].append(entry["scene"])
    for t in tasks.values():
        t["completion_rate"] = round(t["completed"] / t["runs"], 4)
    return {
        "directory": str(directory),
        "version": manifest["version"],
        "seed": manifest.get("seed"),
        "runs": sum(t["runs"] for t in tasks.values()),
        "ticks": sum(t["ticks"] for t in tasks.values()),
        "tasks": {k: tasks[k] for k in sorted(tasks)},
    }
