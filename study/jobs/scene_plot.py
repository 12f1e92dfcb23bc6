"""A scenario drawn as one readable figure: map, obstacles, poses, region, components.

Used by ``asa scenario show`` to write its PNG. The look follows the thesis: the occupancy
grid as background with the question region shaded blue (Fig. 7.48b);
doorways red, gaps orange, the dock green, object surface points blue and wall
surface points violet (Fig. 7.26, 7.29, 7.49).

Matplotlib is used through its object API with the Agg canvas only (no
``pyplot``), so drawing never touches global backend state and works headless.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib import patheffects
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, FancyArrow, Patch, Polygon

from sim.scenario import Scenario
from sim.types import SemanticComponent

COLOURS = {
    "doorway": "#d62728",  # red
    "gap": "#ff7f0e",  # orange
    "dock": "#2ca02c",  # green
    "object": "#1f4fd6",  # blue
    "wall": "#8a2be2",  # violet
    "obstacle": "#404040",
    "inspection": "#e6007e",
    "start": "#111111",
    "region": "#3b7dd8",
}


def draw_scene(
    scenario: Scenario,
    components: Sequence[SemanticComponent],
    *,
    occupied: np.ndarray | None = None,
    extent: tuple[float, float, float, float] | None = None,
    width_in: float = 12.0,
) -> Figure:
    """Draw ``scenario`` and its map-frame ``components`` into a new figure.

    Parameters
    ----------
    scenario : Scenario
        The scene.
    components : sequence of SemanticComponent
        Map-frame components (``sim.semantics.derive_components``).
    occupied : ndarray of bool, shape (rows, cols), optional
        Occupancy grid, row 0 at the bottom, drawn as the background.
    extent : (x_min, x_max, y_min, y_max) [m], optional
        Map extent of ``occupied``; required with it.
    width_in : float
        Figure width [inch]; the height follows the scene's aspect ratio.

    Returns
    -------
    matplotlib.figure.Figure
        A figure with an Agg canvas attached, ready for ``savefig``.
    """
    (x_min, y_min), (x_max, y_max) = scenario.bounds
    if occupied is not None and extent is not None:
        x_min, x_max = min(x_min, extent[0]), max(x_max, extent[1])
        y_min, y_max = min(y_min, extent[2]), max(y_max, extent[3])
    aspect = (y_max - y_min) / max(x_max - x_min, 1e-9)
    fig = Figure(figsize=(width_in, max(3.0, width_in * aspect * 0.9 + 1.0)), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    ax.set_aspect("equal")
    ax.set_xlim(x_min - 0.2, x_max + 0.2)
    ax.set_ylim(y_min - 0.2, y_max + 0.2)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    title = scenario.name + (f" - {scenario.description}" if scenario.description else "")
    ax.set_title(title if len(title) < 110 else title[:107] + "...", fontsize=10)

    if occupied is not None and extent is not None:
        _draw_grid(ax, occupied, extent)
    if len(scenario.question_region) >= 3:
        ax.add_patch(
            Polygon(
                scenario.question_region,
                closed=True,
                facecolor=COLOURS["region"],
                alpha=0.22,
                edgecolor=COLOURS["region"],
                zorder=1,
            )
        )

    _draw_obstacles(ax, scenario)
    _draw_components(ax, components)
    span = max(x_max - x_min, y_max - y_min)
    _draw_pose(ax, scenario.start.x, scenario.start.y, scenario.start.yaw, "A", span)
    if scenario.dock is not None:
        pose = scenario.dock.pose
        _draw_pose(ax, pose.x, pose.y, pose.yaw, "B", span)
    _draw_legend(ax)
    fig.tight_layout()
    return fig


def _draw_grid(ax, occupied: np.ndarray, extent: tuple[float, float, float, float]) -> None:
    """The occupancy grid (rows, cols) as the background, occupied cells grey."""
    ax.imshow(
        np.asarray(occupied, dtype=float),
        origin="lower",
        extent=extent,
        cmap=ListedColormap(["#ffffff", "#b5b5b5"]),
        vmin=0.0,
        vmax=1.0,
        interpolation="nearest",
        zorder=0,
    )


def _draw_legend(ax) -> None:
    """The legend, outside the axes on the right."""
    handles = [
        Patch(facecolor="#b5b5b5", edgecolor="none", label="occupied (grid)"),
        Patch(facecolor="none", edgecolor=COLOURS["obstacle"], label="obstacle outline"),
        Patch(facecolor="none", edgecolor=COLOURS["inspection"], lw=2.5, label="inspection object"),
        Patch(facecolor=COLOURS["region"], alpha=0.22, label="question region"),
        Line2D([], [], color=COLOURS["doorway"], lw=2.5, label="doorway (ends, normal)"),
        Line2D([], [], color=COLOURS["gap"], lw=2.5, label="gap (ends, normal)"),
        Line2D([], [], color=COLOURS["dock"], marker="s", ls="", label="dock (approach)"),
        Line2D([], [], color=COLOURS["object"], marker=".", ls="", label="object surface"),
        Line2D([], [], color=COLOURS["wall"], marker=".", ls="", label="wall surface"),
        Line2D(
            [],
            [],
            color=COLOURS["start"],
            marker=r"$\rightarrow$",
            ls="",
            ms=12,
            label="start A / dock pose B",
        ),
    ]
    ax.legend(
        handles=handles,
        loc="upper left",
        bbox_to_anchor=(1.01, 1.0),
        fontsize=8,
        framealpha=0.95,
        borderaxespad=0.0,
    )


def _draw_obstacles(ax, scenario: Scenario) -> None:
    for wall in scenario.walls:
        ax.add_patch(
            Polygon(
                wall.corners(),
                closed=True,
                facecolor="#6b6b6b",
                edgecolor="#303030",
                lw=0.8,
                zorder=2,
            )
        )
    for box in scenario.boxes:
        highlight = box.name == scenario.inspection_object
        ax.add_patch(
            Polygon(
                box.corners(),
                closed=True,
                facecolor=(*box.colour, 0.55),
                edgecolor=COLOURS["inspection"] if highlight else COLOURS["obstacle"],
                lw=2.8 if highlight else 1.0,
                zorder=2,
            )
        )
    for cyl in scenario.cylinders:
        highlight = cyl.name == scenario.inspection_object
        ax.add_patch(
            Circle(
                cyl.centre,
                cyl.radius,
                facecolor=(*cyl.colour, 0.7),
                edgecolor=COLOURS["inspection"] if highlight else COLOURS["obstacle"],
                lw=2.8 if highlight else 1.0,
                zorder=2,
            )
        )
    _draw_tables(ax, scenario)
    if scenario.inspection_object:
        _label_inspection(ax, scenario)


def _draw_tables(ax, scenario: Scenario) -> None:
    """Each table's top as a dashed outline, its legs filled."""
    for table in scenario.tables:
        hx, hy = table.size[0] / 2, table.size[1] / 2
        c, s = math.cos(table.yaw), math.sin(table.yaw)
        local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
        top = local @ np.array([[c, s], [-s, c]]) + table.centre
        ax.add_patch(
            Polygon(
                top,
                closed=True,
                facecolor="none",
                edgecolor=(*table.colour, 1.0),
                lw=1.0,
                ls="--",
                zorder=2,
            )
        )
        for leg in table.leg_boxes():
            ax.add_patch(
                Polygon(
                    leg.corners(),
                    closed=True,
                    facecolor=(*table.colour, 1.0),
                    edgecolor=COLOURS["obstacle"],
                    lw=0.6,
                    zorder=2,
                )
            )


def _label_inspection(ax, scenario: Scenario) -> None:
    element = scenario.element(scenario.inspection_object)
    ax.annotate(
        f"inspect: {element.name}",
        xy=element.centre,
        xytext=(12, -16),
        textcoords="offset points",
        color=COLOURS["inspection"],
        fontsize=8,
        fontweight="bold",
        zorder=6,
    )


def _draw_components(ax, components: Sequence[SemanticComponent]) -> None:
    halo = [patheffects.withStroke(linewidth=2.2, foreground="white", alpha=0.85)]
    label_style = {
        "fontsize": 6.5,
        "zorder": 7,
        "ha": "center",
        "va": "bottom",
        "path_effects": halo,
    }
    for comp in components:
        colour = COLOURS.get(comp.kind, "black")
        if comp.kind in ("doorway", "gap"):
            ends = np.asarray(comp.ends)
            if len(ends) == 2:
                ax.plot(ends[:, 0], ends[:, 1], color=colour, lw=2.5, zorder=4)
                ax.plot(ends[:, 0], ends[:, 1], ls="", marker="|", color=colour, ms=8, zorder=4)
            _arrow(ax, comp.centre, comp.normal, 0.45, colour)
            ax.plot(*comp.centre, marker="o", color=colour, ms=4, zorder=5)
            ax.text(comp.centre[0], comp.centre[1] + 0.08, comp.id, color=colour, **label_style)
        elif comp.kind == "dock":
            ax.plot(*comp.centre, marker="s", color=colour, ms=8, mec="white", zorder=9)
            _arrow(ax, comp.centre, comp.normal, 0.45, colour)
            ax.text(comp.centre[0], comp.centre[1] + 0.1, comp.id, color=colour, **label_style)
        else:
            pts = np.asarray(comp.points)
            if len(pts):
                ax.plot(pts[:, 0], pts[:, 1], ls="", marker=".", ms=2.2, color=colour, zorder=3)
            ax.text(
                comp.centre[0],
                comp.centre[1],
                comp.id,
                color=colour,
                alpha=0.9,
                **{**label_style, "va": "center"},
            )


def _arrow(ax, start: np.ndarray, direction: np.ndarray, length: float, colour: str) -> None:
    d = np.asarray(direction, dtype=float)
    if not np.all(np.isfinite(d)) or np.hypot(*d) < 1e-12:
        return
    d = d / np.hypot(*d) * length
    ax.add_patch(
        FancyArrow(
            start[0],
            start[1],
            d[0],
            d[1],
            width=0.02,
            head_width=0.12,
            head_length=0.12,
            length_includes_head=True,
            color=colour,
            zorder=5,
        )
    )


def _draw_pose(ax, x: float, y: float, yaw: float, label: str, span: float) -> None:
    length = max(0.5, 0.05 * span)
    ax.add_patch(
        FancyArrow(
            x,
            y,
            length * math.cos(yaw),
            length * math.sin(yaw),
            width=0.05,
            head_width=0.25,
            head_length=0.22,
            length_includes_head=True,
            color=COLOURS["start"],
            zorder=8,
        )
    )
    ax.plot(x, y, marker="o", color=COLOURS["start"], ms=5, zorder=8)
    ax.annotate(
        label,
        xy=(x, y),
        xytext=(-12, 6),
        textcoords="offset points",
        fontsize=13,
        fontweight="bold",
        color=COLOURS["start"],
        zorder=9,
    )


def save_scene_png(
    scenario: Scenario,
    components: Sequence[SemanticComponent],
    path: str | Path,
    *,
    resolution: float = 0.05,
) -> Path:
    """Draw the scene over its occupancy grid and write it as a PNG.

    Parameters
    ----------
    scenario : Scenario
        The scene.
    components : sequence of SemanticComponent
        Its map-frame components.
    path : str or Path
        Output file; its directory must exist.
    resolution : float
        Occupancy-grid cell size [m].

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ValueError
        When the file cannot be written (names the file).
    """
    from sim.occupancy import build_grid  # the grid is the background

    path = Path(path)
    if not path.parent.is_dir():
        raise ValueError(f"{path}: cannot write the PNG: no directory {path.parent}")
    grid = build_grid(scenario, resolution=resolution)
    fig = draw_scene(scenario, components, occupied=grid.occupied, extent=tuple(grid.extent()))
    try:
        fig.savefig(path, format="png", bbox_inches="tight")
    except OSError as error:
        raise ValueError(f"{path}: cannot write the PNG: {error.strerror or error}") from None
    return path
