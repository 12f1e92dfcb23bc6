"""``asa scenario``: list the shipped scenes, show one scene's components, write its map,
check that the robot can drive a scene, generate a random one, build one from a ROS map.

Thin click commands over :mod:`study.jobs.scenes`; bad input is a ``ValueError`` naming
the file (and the field), which the ``asa`` shell prints as one line with exit status 2.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import click

from sim.map_scene import write_scene_from_map
from sim.semantics import derive_components
from study.cli import SEED
from study.jobs.scenes import (
    check,
    describe,
    format_description,
    generate,
    has_display,
    list_scenarios,
    load,
    show_in_gui,
    write_map,
)


@click.group()
def scenario() -> None:
    """Inspect, check and generate scenarios: the shipped list, one scene's semantic
    components, its map, whether the robot can drive it, random floor plans.

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
        if not has_display():
            raise ValueError("asa scenario show --gui: no display (DISPLAY is not set)")
        show_in_gui(
            s,
            opened=lambda: click.echo("pybullet window open; close it (or press Ctrl-C) to return"),
        )


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
    if not math.isfinite(resolution):  # click's range lets nan through
        raise ValueError(f"--resolution: must be a positive number of metres, got {resolution}")
    paths = write_map(s, out, resolution=resolution)
    for kind in ("pgm", "yaml", "png"):
        click.echo(f"{kind:<4}  {paths[kind]}")


@scenario.command("check")
@click.argument("name_or_file", metavar="NAME|FILE")
def check_command(name_or_file: str) -> None:
    """Check that the robot can drive a scenario before anyone does.

    The footprint at A is free; a path leads from A to B and back; the robot fits
    under the dock's table and drives straight in from its open side; the
    inspection object has a free arc to sweep; every doorway and gap can be entered.
    Checks needing a dock, table or inspection object are skipped without one.
    Prints "ok" (exit 0), or one line per problem on stderr (exit status 2).
    """
    s, problems = check(name_or_file)
    if problems:
        for line in problems:
            click.echo(f"asa: {line}", err=True)
        sys.exit(2)
    what = [
        "start",
        *(["route A-B-A", "dock" if s.dock.table else "goal pose"] if s.dock else []),
        *(["inspection arc"] if s.inspection_object else []),
        "passages",
    ]
    click.echo(f"ok  {s.source}: {', '.join(what)}")


@scenario.command("generate")
@click.option("--seed", type=SEED, required=True, help="Random seed (>= 0).")
@click.option(
    "--rooms", type=click.IntRange(3, 6), default=None, help="Rooms in the chain (3-6; drawn)."
)
@click.option(
    "--out",
    "out",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="The scenario TOML file to write.",
)
@click.option("--force", is_flag=True, help="Overwrite --out if it exists.")
def generate_command(seed: int, rooms: int | None, out: Path, force: bool) -> None:
    """Write a random study scene: rooms in a chain, doorways, a row with a gap, maybe
    a corridor, clutter, a table to dock under, an inspection object, a question region.

    The same seed gives the same file, byte for byte; every scene passes
    `asa scenario check`.
    """
    if out.exists() and not force:
        raise ValueError(f"--out {out}: exists already; pass --force to overwrite it")
    path = generate(out, seed=seed, rooms=rooms, force=force)
    click.echo(f"wrote {path}")


def _numbers(flag: str, text: str, count: tuple[int, ...], what: str) -> list[float]:
    """``"1.5,2.4,0"`` -> floats; a ValueError naming the flag unless ``count`` of them."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) not in count or not all(math.isfinite(v) for v in values):
        raise ValueError(f"{flag}: must be {what} (numbers separated by commas), got {text!r}")
    return values


def _placements(
    start: str | None, dock: str | None, tables: tuple[str, ...], inspect: str | None
) -> dict:
    """The placements given as flags, as fields of an additions file."""
    out: dict = {}
    for flag, text, key in (("--start", start, "start"), ("--dock", dock, "dock")):
        if text is not None:
            x, y, yaw = _numbers(flag, text, (3,), "X,Y,YAW with YAW in degrees")
            out[key] = {"x": x, "y": y, "yaw_deg": yaw}
    if tables:
        out["tables"] = []
        for k, text in enumerate(tables):
            v = _numbers("--table", text, (3, 5), "X,Y,YAW or X,Y,YAW,LENGTH,WIDTH")
            table = {"name": f"table_{k}" if k else "table", "centre": v[:2], "yaw_deg": v[2]}
            out["tables"].append(table | ({"size": v[3:]} if len(v) == 5 else {}))
    if inspect is not None:
        out["inspect"] = {"centre": _numbers("--inspect", inspect, (2,), "X,Y")}
    return out


@scenario.command("from-map")
@click.argument("map_yaml", metavar="MAP.yaml", type=click.Path(path_type=Path))
@click.option("--start", help="Pose A: X,Y,YAW [m, m, deg].")
@click.option("--dock", help="Pose B: X,Y,YAW [m, m, deg]; under the first table.")
@click.option(
    "--table",
    "tables",
    multiple=True,
    help="A table: X,Y,YAW or X,Y,YAW,LENGTH,WIDTH [m, deg] (default 1.2 x 0.9 m); repeatable.",
)
@click.option("--inspect", help="The object to inspect, a cylinder at X,Y [m].")
@click.option(
    "--additions",
    type=click.Path(dir_okay=False, path_type=Path),
    help="A TOML file of additions (sim/scenarios/FORMAT.md); flags replace its fields.",
)
@click.option(
    "--out",
    "out",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="The scenario TOML file to write.",
)
@click.option(
    "--semantics",
    type=click.Choice(["map", "geometry"]),
    help="Where doorways, gaps, objects and walls come from: the map image (thesis "
    "Alg. 4-5; the default) or the walls' and boxes' geometry.",
)
@click.option("--force", is_flag=True, help="Overwrite --out if it exists.")
def from_map_command(
    map_yaml: Path,
    start: str | None,
    dock: str | None,
    tables: tuple[str, ...],
    inspect: str | None,
    additions: Path | None,
    out: Path,
    semantics: str | None,
    force: bool,
) -> None:
    """Build a scenario from a ROS map_server map (YAML + PGM/PNG).

    The occupied cells become merged axis-aligned walls and boxes; A, B, tables and
    the object to inspect come from the flags or --additions. The semantic components
    come from the map image (the scene rendered: the map's cells plus the additions)
    unless --semantics geometry or the additions' [semantics] source say otherwise.
    Check the result with `asa scenario check`.
    """
    if out.exists() and not force:
        raise ValueError(f"--out {out}: exists already; pass --force to overwrite it")
    path, counts = write_scene_from_map(
        map_yaml,
        out,
        additions_file=additions,
        placements=_placements(start, dock, tables, inspect),
        semantics=semantics,
        force=True,
    )
    click.echo(
        f"wrote {path}: {counts['walls']} walls and {counts['boxes']} boxes from "
        f"{counts['occupied_cells']} occupied cells"
    )
