"""The report draws paths on the occupancy map the session engine saves beside the
recordings, read without the simulator (analysis.figures.read_map)."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.figures import paths_figure, read_map
from sim.map_files import save_ros_map
from sim.occupancy import build_grid
from sim.scenario import available_scenarios, load_scenario


@pytest.mark.parametrize("name", available_scenarios())
def test_read_map_returns_the_saved_grid_and_its_extent(tmp_path, name):
    grid = build_grid(load_scenario(name))
    save_ros_map(grid, tmp_path, name)
    image, (x0, x1, y0, y1) = read_map(tmp_path / f"{name}.yaml")
    rows, cols = grid.occupied.shape
    assert image.shape == (rows, cols)
    np.testing.assert_array_equal(image[::-1] == 0, grid.occupied)  # row 0 is the top
    assert (x0, y0) == pytest.approx(tuple(grid.origin))
    assert (x1 - x0, y1 - y0) == pytest.approx((cols * grid.resolution, rows * grid.resolution))


def test_a_broken_map_is_a_value_error_naming_the_file(tmp_path):
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n")
    (tmp_path / "m.pgm").write_bytes(b"P2\n2 2\n255\n0 0 0 0\n")
    with pytest.raises(ValueError, match="m.yaml"):
        read_map(tmp_path / "m.yaml")
    (tmp_path / "n.yaml").write_text("resolution: 0.05\n")
    with pytest.raises(ValueError, match="n.yaml"):
        read_map(tmp_path / "n.yaml")


def test_paths_are_drawn_over_the_map(tmp_path):
    import pandas as pd

    grid = build_grid(load_scenario("practice_course"))
    save_ros_map(grid, tmp_path, "practice_course")
    background = read_map(tmp_path / "practice_course.yaml")
    samples = pd.DataFrame({"trial_id": [1, 1, 1], "tick": [0, 1, 2],
                            "x": [1.0, 1.5, 2.0], "y": [2.5, 2.5, 2.6]})  # fmt: skip
    trials = pd.DataFrame({"trial_id": [1], "mode": ["manual"]})
    fig = paths_figure(samples, trials, ("manual",), background)
    ax = fig.axes[0]
    assert len(ax.images) == 1 and ax.images[0].get_extent() == list(background[1])
    assert len(paths_figure(samples, trials, ("manual",)).axes[0].images) == 0
