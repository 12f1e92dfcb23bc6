"""Scenarios for people: load one by name or file, list, describe, write its map, show it.

The plain functions behind ``asa scenario``. Every bad input (a missing or unreadable
file, a directory, malformed TOML, a bad field, an output path that cannot be written)
is raised as ``ValueError`` naming the file (and the field).
"""

from __future__ import annotations

import math
import os
import sys
from collections import Counter
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from sim.scenario import SCENARIO_DIR, Scenario, available_scenarios, load_scenario
from sim.semantics import derive_components
from sim.types import COMPONENT_KINDS, SemanticComponent


def load(name_or_file: str | Path) -> Scenario:
    """Load a shipped scenario by name or a scenario TOML file by path.

    Unlike :func:`sim.scenario.load_scenario`, every failure is a ``ValueError``
    naming the file: also a directory, a missing or unreadable file.
    """
    text = str(name_or_file)
    path = Path(text)
    if path.is_dir():
        shipped = SCENARIO_DIR / f"{text}.toml"
        if not path.suffix and shipped.is_file():  # a shipped name that is also a folder here
            return load_scenario(shipped)
        raise ValueError(f"{path}: is a directory, expected a scenario TOML file or a name")
    try:
        return load_scenario(text)
    except FileNotFoundError:
        raise ValueError(
            f"{path}: no such scenario file "
            f"(shipped scenarios: {', '.join(available_scenarios()) or 'none'})"
        ) from None
    except OSError as error:  # permissions, special files
        raise ValueError(f"{path}: cannot read: {error.strerror or error}") from None


def list_scenarios() -> list[dict[str, str]]:
    """The shipped scenarios: ``[{"name", "description", "source"}]``, sorted by name."""
    out = []
    for name in available_scenarios():
        s = load(name)
        out.append({"name": name, "description": s.description, "source": s.source})
    return out


def _xy(v: Any) -> list[float]:
    return [round(float(x), 6) for x in v]


def _component_dict(c: SemanticComponent) -> dict[str, Any]:
    return {
        "id": c.id,
        "kind": c.kind,
        "centre": _xy(c.centre),
        "ends": [_xy(p) for p in c.ends],
        "width": None if math.isnan(c.width) else round(float(c.width), 6),
        "normal": _xy(c.normal),
        "points_count": len(c.points) if c.kind in ("object", "wall") else 0,
        "source": list(c.source),
    }


def _pose_dict(x: float, y: float, yaw: float) -> dict[str, float]:
    return {"x": round(x, 6), "y": round(y, 6), "yaw_deg": round(math.degrees(yaw), 6)}


def describe(
    scenario: Scenario, components: Sequence[SemanticComponent] | None = None
) -> dict[str, Any]:
    """A JSON-ready summary of a scenario and its semantic components.

    Keys: ``name``, ``source``, ``description``, ``bounds`` ([[x_min, y_min],
    [x_max, y_max]] [m]), ``start`` and ``dock`` (x, y [m], yaw_deg; the dock
    also ``table``, ``tolerance_m``, ``tolerance_deg``; ``None`` without a dock),
    ``elements`` (counts of walls, boxes, cylinders, tables), ``inspection_object``,
    ``question_region`` (polygon [m], [] if none), ``components`` (id, kind, centre,
    ends, width [m] or ``None``, normal, points_count, source) and ``counts``
    (kind -> number of components, every kind listed).
    """
    comps = derive_components(scenario) if components is None else components
    dock = scenario.dock
    counts = Counter(c.kind for c in comps)
    return {
        "name": scenario.name,
        "source": scenario.source,
        "description": scenario.description,
        "bounds": [_xy(scenario.bounds[0]), _xy(scenario.bounds[1])],
        "start": _pose_dict(scenario.start.x, scenario.start.y, scenario.start.yaw),
        "dock": None
        if dock is None
        else {
            **_pose_dict(dock.pose.x, dock.pose.y, dock.pose.yaw),
            "table": dock.table,
            "tolerance_m": dock.tolerance_m,
            "tolerance_deg": round(math.degrees(dock.tolerance_rad), 6),
        },
        "elements": {
            "walls": len(scenario.walls),
            "boxes": len(scenario.boxes),
            "cylinders": len(scenario.cylinders),
            "tables": len(scenario.tables),
        },
        "inspection_object": scenario.inspection_object or None,
        "question_region": [_xy(p) for p in scenario.question_region],
        "components": [_component_dict(c) for c in comps],
        "counts": {kind: counts.get(kind, 0) for kind in COMPONENT_KINDS},
    }


def format_description(summary: dict[str, Any]) -> str:
    """The summary of :func:`describe` as aligned text for a terminal."""
    (x0, y0), (x1, y1) = summary["bounds"]
    start, dock = summary["start"], summary["dock"]
    elements = ", ".join(f"{n} {k}" for k, n in summary["elements"].items())
    lines = [
        f"scenario  {summary['name']}"
        + (f" - {summary['description']}" * bool(summary["description"])),
        f"source    {summary['source'] or '(built in code)'}",
        f"bounds    x {x0:g}..{x1:g} m, y {y0:g}..{y1:g} m",
        f"start A   ({start['x']:g}, {start['y']:g}) m, {start['yaw_deg']:g} deg",
        "dock B    "
        + (
            "none"
            if dock is None
            else f"({dock['x']:g}, {dock['y']:g}) m, {dock['yaw_deg']:g} deg, "
            f"under table {dock['table'] or '-'!s}, tolerance {dock['tolerance_m']:g} m / "
            f"{dock['tolerance_deg']:g} deg"
        ),
        f"elements  {elements}",
        f"inspect   {summary['inspection_object'] or 'none'}",
        "question  "
        + (
            "none"
            if not summary["question_region"]
            else "polygon " + " ".join(f"({x:g}, {y:g})" for x, y in summary["question_region"])
        ),
        "components "
        + ", ".join(f"{n} {k}" for k, n in summary["counts"].items())
        + f" ({len(summary['components'])} in all)",
    ]
    comps = summary["components"]
    if comps:
        width = max(len(c["id"]) for c in comps)
        lines.append("")
        lines.append(f"  {'id':<{width}}  {'kind':<7}  {'centre [m]':<16}  detail")
        for c in comps:
            centre = f"({c['centre'][0]:.2f}, {c['centre'][1]:.2f})"
            if c["kind"] in ("doorway", "gap"):
                w = "?" if c["width"] is None else f"{c['width']:.3f}"
                detail = f"width {w} m, normal ({c['normal'][0]:.2f}, {c['normal'][1]:.2f})"
            elif c["kind"] == "dock":
                detail = f"approach ({c['normal'][0]:.2f}, {c['normal'][1]:.2f})"
            else:
                detail = f"{c['points_count']} surface points"
            if c["source"]:
                detail += f"  [{' / '.join(c['source'])}]"
            lines.append(f"  {c['id']:<{width}}  {c['kind']:<7}  {centre:<16}  {detail}")
    return "\n".join(lines)


def write_map(scenario: Scenario, out: str | Path, *, resolution: float = 0.05) -> dict[str, Path]:
    """Write the scenario's occupancy map as a ROS map (PGM + YAML) and a PNG.

    Parameters
    ----------
    scenario : Scenario
        The scene.
    out : str or Path
        Output directory, created if missing.
    resolution : float
        Cell size [m], > 0.

    Returns
    -------
    dict
        ``{"pgm": path, "yaml": path, "png": path}``; files are named after the scenario.

    Raises
    ------
    ValueError
        A bad resolution, an ``out`` that cannot be made, or a scenario ``name`` that is not
        a plain file name or leads outside ``out`` (nothing is written then).
    """
    from sim.map_files import save_png, save_ros_map
    from sim.occupancy import build_grid
    from study.data.paths import file_in

    if not (math.isfinite(resolution) and resolution > 0):
        raise ValueError(f"resolution: must be a positive number of metres, got {resolution}")
    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise ValueError(f"{out}: cannot create the output directory: {error.strerror}") from None
    if not out.is_dir():
        raise ValueError(f"{out}: is not a directory")
    what = f"{scenario.source}: field 'name'"
    png = file_in(out, scenario.name, ".png", what=what)
    for suffix in (".pgm", ".yaml"):  # the names save_ros_map builds
        file_in(out, scenario.name, suffix, what=what)
    grid = build_grid(scenario, resolution=resolution)
    try:
        pgm, yaml = save_ros_map(grid, out, scenario.name)
        save_png(grid, png)
    except OSError as error:
        raise ValueError(f"{out}: cannot write the map: {error.strerror or error}") from None
    return {"pgm": Path(pgm), "yaml": Path(yaml), "png": Path(png)}


def has_display() -> bool:
    """Whether a window can be opened (on Linux: ``DISPLAY`` is set)."""
    return bool(os.environ.get("DISPLAY")) or not sys.platform.startswith("linux")


def show_in_gui(scenario: Scenario, *, opened: Callable[[], None] | None = None) -> None:
    """Open the scene with the robot at A in pybullet's GUI until the window is closed.

    ``opened`` is called once the window is open (e.g. to tell the user how to close it).
    """
    if not has_display():
        raise ValueError("show_in_gui: no display (DISPLAY is not set)")
    import time

    from sim._pybullet import pybullet
    from sim.world import World, WorldSettings

    with World(scenario, seed=0, settings=WorldSettings(gui=True)) as world:
        world.reset()
        if opened is not None:
            opened()
        try:
            while pybullet.isConnected(physicsClientId=world.client):
                world.step()
                time.sleep(world.settings.dt)
        except (KeyboardInterrupt, pybullet.error):
            pass


def check(name_or_file: str | Path) -> tuple[Scenario, list[str]]:
    """Load a scenario and check that the robot can drive it (:func:`sim.check.check_scene`).

    Returns the scenario and one line per problem, each naming the file and the
    element (empty when the scene passes). Bad input raises ``ValueError``.
    """
    from sim.check import check_scene

    s = load(name_or_file)
    return s, [p.line(s.source) for p in check_scene(s)]


def generate(out: str | Path, *, seed: int, rooms: int | None = None, force: bool = False) -> Path:
    """Write a generated scene (:func:`sim.generate.generate_scene`) to ``out`` as TOML.

    Parameters
    ----------
    out : str or Path
        The file to write; an existing file is refused unless ``force``.
    seed : int
        Seed of the ``numpy.random.Generator``; the same seed gives the same bytes.
    rooms : int, optional
        Rooms in the chain, 3-6 (drawn when omitted).
    force : bool
        Overwrite an existing ``out``.

    Returns
    -------
    Path
        ``out``.
    """
    import numpy as np

    from sim.generate import generate_scene, scene_toml

    out = Path(out)
    if seed < 0:
        raise ValueError(f"seed: must be zero or a positive integer, got {seed}")
    if out.is_dir():
        raise ValueError(f"{out}: is a directory, expected a .toml file to write")
    if out.exists() and not force:
        raise ValueError(f"{out}: exists already; set force to overwrite it")
    data = generate_scene(np.random.default_rng(seed), rooms=rooms)
    data["name"] = f"generated_{seed}" + (f"_{rooms}rooms" if rooms is not None else "")
    header = (
        f"Generated by `asa scenario generate --seed {seed}"
        + (f" --rooms {rooms}" if rooms is not None else "")
        + "` (sim.generate.generate_scene).\nFormat: sim/scenarios/FORMAT.md."
    )
    try:
        out.write_text(scene_toml(data, header=header), encoding="utf-8")
    except OSError as error:
        raise ValueError(f"{out}: cannot write: {error.strerror or error}") from None
    return out
