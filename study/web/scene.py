"""The scene's static part for the page, sent once per scenario: the map's cells (binary
``MAP``, :func:`study.web.messages.pack_map`) and a JSON ``scene`` with the grid's frame and
the object to inspect, as the pygame map draws them (:mod:`study.ui.map_view`)."""

from __future__ import annotations

from typing import Any

from sim.occupancy import OccupancyGrid
from sim.scenario import Scenario
from sim.scene import Box, Cylinder
from study.ui.describe import map_cells
from study.web import messages as wire


def map_message(map_id: int, scenario: Scenario, grid: OccupancyGrid) -> bytes:
    """The ``MAP`` message of ``scenario``."""
    x0, y0 = grid.origin
    return wire.pack_map(map_id, map_cells(scenario, grid), float(grid.resolution), (x0, y0))


def scene_message(map_id: int, scenario: Scenario, *, show_object: bool) -> str:
    """The JSON ``scene`` message: the map's id and, with ``show_object``, the object to
    inspect (a cylinder's centre and radius or a box's centre, size and yaw [m, rad]) in
    its colour (r, g, b in 0-255)."""
    obj: dict[str, Any] | None = None
    if show_object and scenario.inspection_object:
        element = scenario.element(scenario.inspection_object)
        colour = [int(255 * c) for c in element.colour[:3]]
        if isinstance(element, Cylinder):
            obj = {"shape": "cylinder", "centre": list(map(float, element.centre[:2])),
                   "radius": float(element.radius), "colour": colour}  # fmt: skip
        elif isinstance(element, Box):
            obj = {"shape": "box", "centre": list(map(float, element.centre[:2])),
                   "size": list(map(float, element.size[:2])), "yaw": float(element.yaw),
                   "colour": colour}  # fmt: skip
    return wire.server_json("scene", map_id=map_id, object=obj)
