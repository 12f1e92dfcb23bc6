"""``asa scenario``: list the shipped scenes, show one scene's components, write its map.

Thin click commands over plain functions (:func:`load`, :func:`list_scenarios`,
:func:`describe`, :func:`format_description`, :func:`write_map`), usable from
Python as they are.

Every bad input (a missing or unreadable file, a directory, malformed TOML, a
bad field, an output path that cannot be written) is raised as ``ValueError``
naming the file (and the field), which the ``asa`` shell prints as one line
with exit status 2.
"""

from __future__ import annotations

import json
import math
import os
import sys
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import click

from sim.scenario import SCENARIO_DIR, Scenario, available_scenarios, load_scenario
from sim.semantics import derive_components
from sim.types import COMPONENT_KINDS, SemanticComponent

# ---------------------------------------------------------------- plain functions


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
    """
    from sim.map_files import save_png, save_ros_map
    from sim.occupancy import build_grid

    if not (math.isfinite(resolution) and resolution > 0):
        raise ValueError(f"--resolution: must be a positive number of metres, got {resolution}")
    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise ValueError(f"{out}: cannot create the output directory: {error.strerror}") from None
    if not out.is_dir():
        raise ValueError(f"{out}: is not a directory")
    grid = build_grid(scenario, resolution=resolution)
    try:
        pgm, yaml = save_ros_map(grid, out, scenario.name)
        png = out / f"{scenario.name}.png"
        save_png(grid, png)
    except OSError as error:
        raise ValueError(f"{out}: cannot write the map: {error.strerror or error}") from None
    return {"pgm": Path(pgm), "yaml": Path(yaml), "png": Path(png)}


# ----------------------------------------------------------------------- commands


@click.group()
def scenario() -> None:
    """Inspect scenarios: the shipped list, one scene's semantic components, its map.

    NAME|FILE is a shipped scenario's name (see `asa scenario list`) or the path
    of any scenario TOML file (format: sim/scenario.py).
    """


@scenario.command("list")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON array and nothing else.")
def list_command(as_json: bool) -> None:
    """List the shipped scenarios with their descriptions."""
    rows = list_scenarios()
    if as_json:
        click.echo(json.dumps(rows))
        return
    if not rows:
        click.echo("no shipped scenarios")
        return
    width = max(len(r["name"]) for r in rows)
    for r in rows:
        click.echo(f"{r['name']:<{width}}  {r['description']}")


@scenario.command("show")
@click.argument("name_or_file", metavar="NAME|FILE")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object and nothing else.")
@click.option(
    "--png",
    "png",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Also draw the scene (map, obstacles, A and B, region, components) to this PNG.",
)
@click.option(
    "--gui",
    is_flag=True,
    help="Also open the scene in pybullet's 3D window (needs a display; close it to return).",
)
def show_command(name_or_file: str, as_json: bool, png: Path | None, gui: bool) -> None:
    """Show a scenario's summary and every semantic component.

    Components are derived from the geometry: doorways (between two walls) and
    gaps (next to a free-standing obstacle) with their width and crossing normal,
    one dock per table, objects and wall segments with their surface points.
    """
    s = load(name_or_file)
    components = derive_components(s)
    summary = describe(s, components)
    if png is not None:
        from study.jobs.scene_plot import save_scene_png

        save_scene_png(s, components, png)
    if as_json:
        click.echo(json.dumps(summary))
        return
    click.echo(format_description(summary))
    if png is not None:
        click.echo(f"\nwrote {png}")
    if gui:
        show_in_gui(s)


def show_in_gui(scenario: Scenario) -> None:
    """Open the scene with the robot at A in pybullet's GUI until the window is closed."""
    if not os.environ.get("DISPLAY") and sys.platform.startswith("linux"):
        raise ValueError("asa scenario show --gui: no display (DISPLAY is not set)")
    import time

    from sim._pybullet import pybullet
    from sim.world import World, WorldSettings

    with World(scenario, seed=0, settings=WorldSettings(gui=True)) as world:
        world.reset()
        click.echo("pybullet window open; close it (or press Ctrl-C) to return")
        try:
            while pybullet.isConnected(physicsClientId=world.client):
                world.step()
                time.sleep(world.settings.dt)
        except (KeyboardInterrupt, pybullet.error):
            pass


@scenario.command("map")
@click.argument("name_or_file", metavar="NAME|FILE")
@click.option(
    "--out",
    "out",
    required=True,
    type=click.Path(file_okay=False, path_type=Path),
    help="Directory for the map files (created if missing).",
)
@click.option(
    "--resolution",
    type=click.FloatRange(min=0.0, min_open=True, max=1.0),
    default=0.05,
    show_default=True,
    help="Cell size [m].",
)
def map_command(name_or_file: str, out: Path, resolution: float) -> None:
    """Write the scenario's occupancy map: ROS map (PGM + YAML) and a PNG."""
    s = load(name_or_file)
    derive_components(s)  # a malformed [semantics] table is reported here too
    paths = write_map(s, out, resolution=resolution)
    for kind in ("pgm", "yaml", "png"):
        click.echo(f"{kind:<4}  {paths[kind]}")
