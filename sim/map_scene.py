"""From a ROS map to a scene: the occupied cells of a ``map_server`` map as merged
axis-aligned rectangles, plus the placements a map cannot show (issue 23; thesis Sec.
7.6.1.1: the study scene is a building the robot mapped).

:func:`occupied_rectangles` covers the occupied cells exactly with few rectangles.
:func:`scene_from_map` turns a map (:func:`sim.map_files.load_ros_map`) and the
additions (start A, dock B, tables, the object to inspect, question region; the TOML
format in ``sim/scenarios/FORMAT.md``) into scenario data: every rectangle of a blob
at least ``wall_min_length_m`` long becomes a wall, of a smaller blob a box; cells
under an added table or object are cleared first (the map shows its legs or outline,
the addition replaces them). :func:`write_scene_from_map` validates the result with
the scenario loader and writes it.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage

from sim.limits import loads_toml
from sim.map_files import load_ros_map
from sim.occupancy import OccupancyGrid
from sim.scenario import parse_scenario
from sim.toml_text import dumps

MAP_SETTINGS = {  # the [map] table of an additions file, with its defaults
    "wall_min_length_m": 1.0,  # [m] a blob whose bounding box is this long is a wall
    "wall_height": 1.2,  # [m]
    "box_height": 0.8,  # [m]
    "clear_margin_m": 0.1,  # [m] map cells this close to an added element are cleared
    "min_blob_cells": 1,  # blobs of fewer occupied cells (speckle) are dropped
}
INSPECT_DEFAULTS = {"radius": 0.2, "height": 1.0, "colour": [0.9, 0.1, 0.1]}
TABLE_DEFAULTS = {"size": [1.2, 0.9], "height": 0.75}
INSPECT_NAME = "inspect_object"
_ADDITION_KEYS = (
    "name",
    "description",
    "start",
    "dock",
    "tables",
    "boxes",
    "cylinders",
    "inspect",
    "inspection_object",
    "question_region",
    "robot",
    "semantics",
    "map",
)


# -------------------------------------------------------------------- rectangles


def _run_rectangles(occupied: np.ndarray) -> np.ndarray:
    """Row runs merged downwards while identical: a partition of the occupied cells
    into rectangles (k, 4) int ``(row0, col0, row1, col1)``, half-open."""
    rows, cols = occupied.shape
    pad = np.zeros((rows, cols + 2), dtype=np.int8)
    pad[:, 1:-1] = occupied
    step = np.diff(pad, axis=1)
    run_row, run_c0 = np.nonzero(step == 1)
    _, run_c1 = np.nonzero(step == -1)  # same order: row-major, one end per start
    bounds = np.searchsorted(run_row, np.arange(rows + 1))
    out: list[tuple[int, int, int, int]] = []
    open_runs: dict[tuple[int, int], int] = {}  # (col0, col1) -> first row
    for r in range(rows + 1):
        lo, hi = (bounds[r], bounds[r + 1]) if r < rows else (0, 0)
        runs = set(zip(run_c0[lo:hi].tolist(), run_c1[lo:hi].tolist(), strict=True))
        for key, r0 in list(open_runs.items()):
            if key not in runs:
                out.append((r0, key[0], r, key[1]))
                del open_runs[key]
        for key in runs:
            open_runs.setdefault(key, r)
    return np.array(out, dtype=np.int64).reshape(-1, 4)


def occupied_rectangles(occupied: np.ndarray) -> np.ndarray:
    """Axis-aligned rectangles whose union is exactly the occupied cells.

    Parameters
    ----------
    occupied : (rows, cols) bool

    Returns
    -------
    (k, 4) int
        ``(row0, col0, row1, col1)``, half-open cell ranges; rectangles may overlap.

    Notes
    -----
    Candidates are the row-run partition (runs merged with identical runs below) and
    the column-run partition; taken largest first, a candidate is kept when it covers
    a cell no kept one covers. A wall along either axis so becomes few rectangles.
    """
    occupied = np.asarray(occupied, dtype=bool)
    if occupied.ndim != 2:
        raise ValueError(f"occupied must be a 2-D bool array, got shape {occupied.shape}")
    by_row = _run_rectangles(occupied)
    by_col = _run_rectangles(np.ascontiguousarray(occupied.T))[:, [1, 0, 3, 2]]
    candidates = np.vstack((by_row, by_col))
    area = (candidates[:, 2] - candidates[:, 0]) * (candidates[:, 3] - candidates[:, 1])
    covered = np.zeros(occupied.shape, dtype=bool)
    keep = []
    for k in np.argsort(-area, kind="stable"):
        r0, c0, r1, c1 = candidates[k]
        view = covered[r0:r1, c0:c1]
        if not view.all():
            keep.append(k)
            view[...] = True
    keep.sort()
    return candidates[keep]


# ------------------------------------------------------------------- the elements


def _fail(source: str, field: str, message: str) -> ValueError:
    return ValueError(f"{source}: field '{field}': {message}")


def _number(source: str, table: dict, key: str, where: str, default: float) -> float:
    value = table.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise _fail(source, f"{where}{key}", f"must be a finite number, got {value!r}")
    if value < 0:
        raise _fail(source, f"{where}{key}", f"must be zero or positive, got {value!r}")
    return float(value)


def _map_settings(additions: dict[str, Any], source: str) -> dict[str, float]:
    table = additions.get("map", {})
    if not isinstance(table, dict):
        raise _fail(source, "map", "must be a table")
    unknown = sorted(set(table) - set(MAP_SETTINGS))
    if unknown:
        raise _fail(
            source, f"map.{unknown[0]}", f"is not a known field (known: {', '.join(MAP_SETTINGS)})"
        )
    out = {k: _number(source, table, k, "map.", d) for k, d in MAP_SETTINGS.items()}
    for key in ("wall_height", "box_height"):
        if out[key] <= 0:
            raise _fail(source, f"map.{key}", f"must be positive, got {out[key]}")
    return out


def _footprints(data: dict[str, Any]) -> list[tuple[np.ndarray, float, float]]:
    """Each added element as (centre (2,) [m], yaw [rad], half extents or radius):
    ``(centre, yaw, hx, hy)`` for tables and boxes, ``(centre, 0, r, -1)`` for
    cylinders. Entries the scenario loader will refuse are skipped here."""
    out = []
    for t in (*data.get("tables", []), *data.get("boxes", [])):
        try:
            centre = np.array(t["centre"], dtype=float).reshape(2)
            hx, hy = (float(v) / 2 for v in t["size"])
            out.append((centre, math.radians(float(t.get("yaw_deg", 0.0))), hx, hy))
        except (KeyError, TypeError, ValueError):
            continue
    for c in data.get("cylinders", []):
        try:
            out.append((np.array(c["centre"], dtype=float).reshape(2), 0.0, float(c["radius"]), -1))
        except (KeyError, TypeError, ValueError):
            continue
    return out


def _clear_added(grid: OccupancyGrid, data: dict[str, Any], margin: float) -> np.ndarray:
    """The grid's occupied cells (rows, cols) bool, without those whose centre lies
    within ``margin`` [m] of an added table, box or cylinder."""
    occupied = grid.occupied.copy()
    rows, cols = occupied.shape
    rc = np.argwhere(np.ones((rows, cols), dtype=bool))
    xy = grid.cell_to_world(rc).reshape(rows, cols, 2)
    for centre, yaw, hx, hy in _footprints(data):
        d = xy - centre
        if hy < 0:  # a cylinder of radius hx
            inside = np.hypot(d[..., 0], d[..., 1]) <= hx + margin
        else:
            c, s = math.cos(yaw), math.sin(yaw)
            u, v = c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]
            inside = (np.abs(u) <= hx + margin) & (np.abs(v) <= hy + margin)
        occupied &= ~inside
    return occupied


def _map_elements(grid: OccupancyGrid, occupied: np.ndarray, settings: dict) -> dict[str, list]:
    """Walls and boxes of the map's occupied cells: rectangles of blobs (8-connected)
    whose bounding box reaches ``wall_min_length_m`` are walls, the others boxes (blobs
    of fewer than ``min_blob_cells`` cells are dropped as speckle); the
    rectangles of one blob share the group ``blob_<k>`` (one obstacle: no passage
    between its parts)."""
    labels, n = ndimage.label(occupied, structure=np.ones((3, 3), dtype=bool))
    sizes = np.bincount(labels.ravel(), minlength=n + 1)
    occupied = occupied & (sizes[labels] >= settings["min_blob_cells"])
    spans = ndimage.find_objects(labels)
    res, (x0, y0) = grid.resolution, grid.origin
    long_enough = [
        max(s[0].stop - s[0].start, s[1].stop - s[1].start) * res
        >= settings["wall_min_length_m"] - 1e-9
        for s in spans
    ]
    walls, boxes = [], []
    for r0, c0, r1, c1 in occupied_rectangles(occupied).tolist():
        blob = int(labels[r0, c0])
        xa, xb, ya, yb = x0 + c0 * res, x0 + c1 * res, y0 + r0 * res, y0 + r1 * res
        if long_enough[blob - 1]:
            horizontal = xb - xa >= yb - ya
            ym, xm = (ya + yb) / 2, (xa + xb) / 2
            walls.append(
                {
                    "name": f"map_wall_{len(walls)}",
                    "from": [xa, ym] if horizontal else [xm, ya],
                    "to": [xb, ym] if horizontal else [xm, yb],
                    "thickness": (yb - ya) if horizontal else (xb - xa),
                    "height": settings["wall_height"],
                    "group": f"blob_{blob}",
                }
            )
        else:
            boxes.append(
                {
                    "name": f"map_box_{len(boxes)}",
                    "centre": [(xa + xb) / 2, (ya + yb) / 2],
                    "size": [xb - xa, yb - ya],
                    "height": settings["box_height"],
                    "group": f"blob_{blob}",
                }
            )
    return {"walls": walls, "boxes": boxes}


# --------------------------------------------------------------------- the scene


def _scene_name(data: dict[str, Any], map_yaml: Path) -> str:
    if "name" in data:
        return data["name"]
    name = "".join(ch if ch.isalnum() or ch in "_-" else "_" for ch in map_yaml.stem)
    return (name.lstrip("_-") or "map_scene")[:64]


def _with_defaults(data: dict[str, Any], source: str) -> dict[str, Any]:
    """The additions with table defaults filled in and ``[inspect]`` as a cylinder."""
    out = dict(data)
    tables = out.get("tables", [])
    if isinstance(tables, list):
        out["tables"] = [{**TABLE_DEFAULTS, **t} if isinstance(t, dict) else t for t in tables]
    inspect = out.pop("inspect", None)
    if inspect is not None:
        if not isinstance(inspect, dict) or "centre" not in inspect:
            raise _fail(source, "inspect", "must be a table with centre = [x, y]")
        if "inspection_object" in out:
            raise _fail(source, "inspect", "give either [inspect] or inspection_object, not both")
        cylinder = {"name": INSPECT_NAME, **INSPECT_DEFAULTS, **inspect}
        out["cylinders"] = [cylinder, *out.get("cylinders", [])]
        out["inspection_object"] = cylinder["name"]
    return out


def _map_semantics(table: Any, source: str) -> dict[str, Any]:
    """The scene's ``[semantics]``: the additions' table with ``source = "map"`` unless
    it names one (the map image, as the scene renders it, has the map's doorways; the
    geometry of one wall blob has none)."""
    if not isinstance(table, dict):
        raise _fail(source, "semantics", "must be a table")
    if "map" in table:
        raise _fail(source, "semantics.map", "from-map scenes read the map they are built of")
    return {"source": "map", **table}


def scene_from_map(map_yaml: str | Path, additions: dict[str, Any], *, source: str) -> dict:
    """Scenario data (the dict a scenario TOML file holds) from a ROS map and additions.

    Parameters
    ----------
    map_yaml : str or Path
        The map's YAML file (:func:`sim.map_files.load_ros_map`).
    additions : dict
        What the map cannot show, as in a scenario file (``start``, ``dock``,
        ``tables``, ``boxes``, ``cylinders``, ``inspection_object``,
        ``question_region``, ``robot``, ``semantics``, ``name``, ``description``),
        plus ``inspect`` (a cylinder to inspect: ``centre``, optional ``radius``,
        ``height``, ``colour``) and ``map`` (:data:`MAP_SETTINGS`).
    source : str
        Named in error messages (the additions file, or the map's YAML).

    Returns
    -------
    dict
        Validated by :func:`sim.scenario.parse_scenario`: bounds the map's extent,
        added elements first, then ``map_wall_<k>`` and ``map_box_<k>``.

    Raises
    ------
    ValueError
        Naming the file and field: a bad map file, an unknown or bad addition, a
        placement the loader refuses (A or B inside an obstacle or off the map).
    """
    path = Path(map_yaml)
    try:
        grid = load_ros_map(path)
    except FileNotFoundError:
        raise ValueError(f"{path}: no such map file (a ROS map_server YAML)") from None
    unknown = sorted(set(additions) - set(_ADDITION_KEYS))
    if unknown:
        raise _fail(
            source, unknown[0], f"is not a known field (known: {', '.join(_ADDITION_KEYS)})"
        )
    if "start" not in additions:
        raise _fail(source, "start", "is required: pose A as x, y, yaw_deg")
    settings = _map_settings(additions, source)
    data = _with_defaults({k: v for k, v in additions.items() if k != "map"}, source)
    elements = _map_elements(grid, _clear_added(grid, data, settings["clear_margin_m"]), settings)
    x0, y0, x1, y1 = (grid.extent()[i] for i in (0, 2, 1, 3))
    scene: dict[str, Any] = {
        "name": _scene_name(data, path),
        "description": data.get("description", f"From the ROS map {path.name}"),
        "bounds": [[x0, y0], [x1, y1]],
    }
    for key in ("inspection_object", "start", "dock", "question_region", "robot", "semantics"):
        if key in data:
            scene[key] = data[key]
    scene["semantics"] = _map_semantics(scene.get("semantics", {}), source)
    for key in ("tables", "cylinders"):
        if data.get(key):
            scene[key] = data[key]
    scene["boxes"] = [*data.get("boxes", []), *elements["boxes"]]
    scene["walls"] = elements["walls"]
    parse_scenario(scene, source)
    return scene


def write_scene_from_map(
    map_yaml: str | Path,
    out: str | Path,
    *,
    additions_file: str | Path | None = None,
    placements: dict[str, Any] | None = None,
    semantics: str | None = None,
    force: bool = False,
) -> tuple[Path, dict[str, int]]:
    """Write the scenario of a ROS map with its additions to ``out``.

    ``additions_file`` is a TOML file of additions (format: ``sim/scenarios/FORMAT.md``);
    ``placements`` (e.g. from the command line) replace its fields of the same name;
    ``semantics`` ("map" or "geometry") replaces the additions' ``[semantics] source``.
    Returns the path written and counts: ``walls``, ``boxes`` (from the map) and
    ``occupied_cells``.
    """
    out = Path(out)
    if out.exists() and not force:
        raise ValueError(f"{out}: exists already; pass force to overwrite it")
    additions: dict[str, Any] = {}
    source = str(map_yaml)
    if additions_file is not None:
        source = str(additions_file)
        try:
            text = Path(additions_file).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as error:
            raise ValueError(f"{source}: cannot read the additions file: {error}") from None
        additions = loads_toml(text, source)
    additions = {**additions, **(placements or {})}
    if semantics is not None:
        table = additions.get("semantics", {})
        additions["semantics"] = {**(table if isinstance(table, dict) else {}), "source": semantics}
    scene = scene_from_map(map_yaml, additions, source=source)
    try:
        body = dumps(scene)
    except ValueError as error:
        raise ValueError(f"{source}: {error} (from-map writes the flat scenario subset)") from None
    walls = [w for w in scene["walls"] if w["name"].startswith("map_wall_")]
    boxes = [b for b in scene["boxes"] if b["name"].startswith("map_box_")]
    header = (
        f"# Written by `asa scenario from-map` from the ROS map {Path(map_yaml).name}:\n"
        f"# {len(walls)} walls and {len(boxes)} boxes cover its occupied cells; regenerate\n"
        "# rather than edit them (sim/scenarios/FORMAT.md, 'Scenes from ROS maps').\n\n"
    )
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(header + body, encoding="utf-8")
    except OSError as error:
        raise ValueError(f"{out}: cannot write: {error.strerror or error}") from None
    cells = int(load_ros_map(map_yaml).occupied.sum())
    return out, {"walls": len(walls), "boxes": len(boxes), "occupied_cells": cells}
