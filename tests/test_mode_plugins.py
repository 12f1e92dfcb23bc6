"""Modes from outside the package (issue 23): the example collision-filter package installs
with pip and registers itself through the ``asa_study.modes`` entry points; a protocol may
name a mode as ``"package.module:factory"``; a third-party mode runs a counterbalanced
synthetic study and appears in the report like the built-in ones; broken plugins give one
line and exit 2."""

from __future__ import annotations

import os
import sqlite3
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from autonomy.modes import make_mode, mode_factory
from autonomy.types import RobotModel

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "collision_filter"

FOUR = """
[study]
name = "four-modes"
participants = 4
seed = 3

[modes]
names = ["manual", "reactive_bn", "contextual_task", "{plugin}"]
counterbalancing = "williams"

[[phases]]
kind = "baseline"
questions = 3

[[phases]]
kind = "main"
scenario = "practice_course"
route = ["A", "B"]
inspection = false
secondary = false
timeout_s = 90.0

[phases.after_trial]
instrument = "nasa_tlx"
weights = "per_trial"

[analysis]
metrics = ["completion_time_s", "collisions", "score_s", "tlx_raw"]
"""


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The example package installed with pip into a folder of its own (put on
    PYTHONPATH of the commands that use it)."""
    target = tmp_path_factory.mktemp("site")
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--target",
         str(target), str(EXAMPLE)],
        check=True, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    return target


def _run(site: Path | None, *args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    paths = [str(p) for p in (site, cwd) if p is not None]
    env["PYTHONPATH"] = os.pathsep.join([*paths, env.get("PYTHONPATH", "")])
    return subprocess.run(
        [sys.executable, *args], capture_output=True, text=True, timeout=600, env=env, cwd=cwd
    )


def test_the_installed_package_registers_its_mode(site):
    done = _run(site, "-c", "from autonomy.modes import available_modes as a; print(a())")
    assert done.returncode == 0, done.stderr
    assert "collision_filter" in done.stdout and "contextual_task" in done.stdout


def test_a_four_mode_study_with_the_plugin_runs_and_is_reported(site, tmp_path, seed):
    proto = tmp_path / "four.toml"
    proto.write_text(FOUR.format(plugin="collision_filter"))
    db = tmp_path / "four.db"
    done = _run(site, "-m", "study.cli", "synth", "--protocol", str(proto), "--participants",
                "4", "--seed", str(seed % 10_000), "--workers", "2", "--db", str(db),
                "--no-recordings")  # fmt: skip
    assert done.returncode == 0, done.stderr
    conn = sqlite3.connect(db)
    orders = [
        [m for (m,) in conn.execute(
            "SELECT mode FROM trial WHERE participant_id = ? AND phase = 'main' ORDER BY ordinal",
            (pid,))]
        for (pid,) in conn.execute("SELECT id FROM participant ORDER BY id")
    ]  # fmt: skip
    conn.close()
    # a Williams square of four modes: each mode once in each position over 4 participants
    assert all(sorted(o) == sorted(orders[0]) for o in orders) and len(orders[0]) == 4
    assert all(len({o[i] for o in orders}) == 4 for i in range(4))
    assert "collision_filter" in orders[0]
    # the protocol's planned metrics only: ~7 s instead of ~15 s for every metric with data
    # (test_report.py builds the report of every metric)
    planned = ("completion_time_s", "collisions", "score_s", "tlx_raw")
    metrics = [arg for m in planned for arg in ("--metric", m)]
    done = _run(site, "-m", "study.cli", "report", "--db", str(db), "--out", str(tmp_path / "r"),
                *metrics)  # fmt: skip
    assert done.returncode == 0, done.stderr
    html = (tmp_path / "r" / "report.html").read_text()
    assert html.count("collision_filter") >= 4  # in the tables like manual
    assert html.count("collision_filter") >= html.count("reactive_bn") // 2


BROKEN = {
    "broken_import.py": "raise ImportError('the lab forgot a dependency')\n",
    "no_interface.py": "def make(**settings):\n    return object()\n",
    "not_callable.py": "make = 3\n",
}


@pytest.mark.parametrize(
    ("name", "message"),
    [
        ("broken_import:make", "cannot load 'make' from module 'broken_import' (ImportError: "
                               "the lab forgot a dependency)"),
        ("no_interface:make", "its factory returned a object, which has no reset() and no step()"),
        ("not_callable:make", "is not callable"),
        ("no_such_module:make", "cannot load 'make' from module 'no_such_module'"),
        ("broken_entry", "entry point broken_entry = 'missing_module:make' of group "
                         "asa_study.modes"),
        ("no_such_mode", "unknown mode 'no_such_mode'"),
    ],
)  # fmt: skip
def test_a_broken_plugin_is_one_line_and_exit_2(tmp_path, name, message):
    for file, text in BROKEN.items():
        (tmp_path / file).write_text(text)
    info = tmp_path / "broken_entry-0.1.dist-info"  # an installed package whose entry point
    info.mkdir()  # names a module that is not there
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: broken-entry\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[asa_study.modes]\nbroken_entry = missing_module:make\n"
    )
    proto = tmp_path / "p.toml"
    proto.write_text(FOUR.format(plugin=name))
    done = _run(None, "-m", "study.cli", "plan", "--protocol", str(proto), cwd=tmp_path)
    assert done.returncode == 2, done.stdout + done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0] and "names[3]" in lines[0], done.stderr


def test_a_module_reference_builds_the_mode_in_process(tmp_path, monkeypatch, rng):
    monkeypatch.syspath_prepend(str(EXAMPLE))
    name = "asa_collision_filter:make_collision_filter"
    assert mode_factory(name) is mode_factory(name)  # loaded once
    mode = make_mode(name, projection_time_s=1.0)
    mode.reset(RobotModel(footprint=np.array([[0.3, 0.2], [-0.3, 0.2], [-0.3, -0.2], [0.3, -0.2]])))

    class Obs:
        points = np.array([[1.0, y] for y in np.linspace(-1, 1, 41)])  # a wall 1 m ahead

    fast = mode.step(Obs, np.array([1.0, 0.0, 0.0]))  # the wall reached in about 0.65 s
    assert 0.0 < fast.v[0] < 1.0 and fast.beta == pytest.approx(1 - fast.v[0])
    away = mode.step(Obs, np.array([-0.5, 0.3, 0.2]))  # driving away: unchanged
    assert np.array_equal(away.v, [-0.5, 0.3, 0.2]) and away.beta == 0.0
    Obs.points = np.array([[0.32, 0.0]])  # already at the bumper: stop
    assert np.array_equal(mode.step(Obs, np.array([0.5, 0.0, 0.0])).v, [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="unknown setting 'horizon'"):
        make_mode(name, horizon=2.0)
