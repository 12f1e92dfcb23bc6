"""Recording and loading demonstrations (study/jobs/demonstrations/) and
``asa demonstrations`` (study/cli/demonstrations.py)."""

from __future__ import annotations

import hashlib
import io
import json
import os
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

from autonomy.features import task_features
from study.cli import main
from study.jobs.demonstrations import (
    MANIFEST,
    load_demonstrations,
    plan_recording,
    record_demonstrations,
    summarise,
)
from tasks.contextual import DEFAULT_SCENES, DEMONSTRATED


@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> Path:
    """Two runs of object bypass (the quickest task) and one of wall following."""
    seed = int(os.environ.get("ASA_TEST_SEED", "20261123"))
    out = tmp_path_factory.mktemp("demos")
    record_demonstrations(out, plan_recording("object_bypass", None), 2, seed=seed)
    record_demonstrations(out, plan_recording("wall_following", None), 1, seed=seed)
    return out


def _copy(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


def _rehash(directory: Path, rel: str) -> None:
    manifest = json.loads((directory / MANIFEST).read_text())
    for entry in manifest["runs"]:
        if entry["file"] == rel:
            entry["sha256"] = hashlib.sha256((directory / rel).read_bytes()).hexdigest()
    (directory / MANIFEST).write_text(json.dumps(manifest))


def _rewrite(path: Path, change) -> None:
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    change(arrays)
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    path.write_bytes(buffer.getvalue())


def test_plan_recording():
    assert plan_recording("all", None) == [(t, DEFAULT_SCENES[t]) for t in DEMONSTRATED]
    assert plan_recording("gap_crossing", "x") == [("gap_crossing", "x")]
    with pytest.raises(ValueError, match="task: unknown task type.*allowed"):
        plan_recording("flying", None)


def test_recording_round_trips_with_consistent_shapes(recorded):
    manifest = json.loads((recorded / MANIFEST).read_text())
    assert manifest["version"] == 1
    files = [r["file"] for r in manifest["runs"]]
    assert files == sorted(
        [f"object_bypass/demo_object_bypass_run_{k}.npz" for k in (0, 1)]
        + ["wall_following/demo_wall_following_run_0.npz"]
    )
    for r in manifest["runs"]:
        assert hashlib.sha256((recorded / r["file"]).read_bytes()).hexdigest() == r["sha256"]
        assert r["direction"] in ("left", "right")

    every = load_demonstrations(recorded, moving_only=False)
    d = load_demonstrations(recorded)
    assert sum(r["ticks"] for r in manifest["runs"]) == len(every)
    assert sum(r["moving_ticks"] for r in manifest["runs"]) == len(d) < len(every)
    n = len(d)
    assert d.q.shape == (n, 6) and d.s.shape == (n, 2) and d.u.shape == (n, 3)
    assert d.pose_true.shape == d.pose_est.shape == (n, 3)
    assert d.run.shape == d.task.shape == d.target.shape == d.t.shape == (n,)
    assert set(d.task) == {"object_bypass", "wall_following"}
    assert np.all(np.hypot(d.u[:, 0], d.u[:, 1]) > 0)  # only moving ticks
    assert np.allclose(d.u_norm, d.u / np.array([1.0, 1.0, 1.2]))
    for i in range(n):  # q recomputable from s and u
        assert np.allclose(task_features(d.s[i], d.u_norm[i])[0], d.q[i])
    # ragged candidates: the demonstrated target is among them, with the same point
    assert d.cand_offsets.shape == (n + 1,) and d.cand_offsets[-1] == len(d.cand_points)
    assert len(d.cand_ids) == len(d.cand_kinds) == len(d.cand_points)
    for i in range(0, n, 7):
        ids, points = d.candidates(i)
        assert len(ids) >= 2
        hit = np.flatnonzero(ids == d.target[i])
        assert len(hit) == 1
        assert np.allclose(points[hit[0]], d.s[i])
    # the estimate is close to the truth
    assert np.max(np.hypot(*(d.pose_true[:, :2] - d.pose_est[:, :2]).T)) < 0.1


def test_recording_is_reproducible(tmp_path, seed):
    a, b = tmp_path / "a", tmp_path / "b"
    for out in (a, b):
        record_demonstrations(out, [("object_bypass", "demo_object_bypass")], 1, seed=seed)
    assert (a / MANIFEST).read_bytes() == (b / MANIFEST).read_bytes()
    rel = "object_bypass/demo_object_bypass_run_0.npz"
    assert (a / rel).read_bytes() == (b / rel).read_bytes()


def test_summary_counts(recorded):
    summary = summarise(recorded)
    assert summary["runs"] == 3
    assert summary["tasks"]["object_bypass"]["runs"] == 2
    assert summary["tasks"]["wall_following"]["runs"] == 1
    for t in summary["tasks"].values():
        assert 0.0 <= t["completion_rate"] <= 1.0
        assert t["moving_ticks"] <= t["ticks"]


def test_missing_manifest_is_named(tmp_path):
    with pytest.raises(ValueError, match="manifest.json"):
        load_demonstrations(tmp_path)
    with pytest.raises(ValueError, match="not a directory"):
        load_demonstrations(tmp_path / "nowhere")


def test_hash_mismatch_names_the_file(recorded, tmp_path):
    d = _copy(recorded, tmp_path / "d")
    rel = "object_bypass/demo_object_bypass_run_1.npz"
    data = bytearray((d / rel).read_bytes())
    data[len(data) // 2] ^= 0xFF
    (d / rel).write_bytes(bytes(data))
    with pytest.raises(ValueError, match=r"demo_object_bypass_run_1\.npz.*sha256"):
        load_demonstrations(d)
    with pytest.raises(ValueError, match=r"demo_object_bypass_run_1\.npz"):
        summarise(d)


def test_corrupted_file_names_the_file(recorded, tmp_path):
    d = _copy(recorded, tmp_path / "d")
    rel = "object_bypass/demo_object_bypass_run_0.npz"
    (d / rel).write_bytes(b"not a zip file at all")
    _rehash(d, rel)
    with pytest.raises(ValueError, match=r"demo_object_bypass_run_0\.npz.*readable"):
        load_demonstrations(d)


def test_missing_file_names_the_file(recorded, tmp_path):
    d = _copy(recorded, tmp_path / "d")
    rel = "wall_following/demo_wall_following_run_0.npz"
    (d / rel).unlink()
    with pytest.raises(ValueError, match=r"demo_wall_following_run_0\.npz.*missing"):
        load_demonstrations(d)


def test_missing_array_and_wrong_shape_name_the_field(recorded, tmp_path):
    rel = "object_bypass/demo_object_bypass_run_0.npz"
    d = _copy(recorded, tmp_path / "missing")
    _rewrite(d / rel, lambda a: a.pop("q"))
    _rehash(d, rel)
    with pytest.raises(ValueError, match=r"run_0\.npz.*'q'.*missing"):
        load_demonstrations(d)
    d = _copy(recorded, tmp_path / "shape")
    _rewrite(d / rel, lambda a: a.update(s=a["s"][:, :1]))
    _rehash(d, rel)
    with pytest.raises(ValueError, match=r"run_0\.npz.*'s'.*shape"):
        load_demonstrations(d)
    d = _copy(recorded, tmp_path / "pickled")
    _rewrite(d / rel, lambda a: a.update(phase=np.array([{"x": 1}] * len(a["t"]))))
    _rehash(d, rel)
    with pytest.raises(ValueError, match=r"run_0\.npz"):
        load_demonstrations(d)


def test_bad_manifest_fields_are_named(recorded, tmp_path):
    d = _copy(recorded, tmp_path / "d")
    manifest = json.loads((d / MANIFEST).read_text())
    manifest["runs"][0]["task"] = "dancing"
    (d / MANIFEST).write_text(json.dumps(manifest))
    with pytest.raises(ValueError, match=r"manifest\.json.*runs\[0\]\.task"):
        load_demonstrations(d)
    (d / MANIFEST).write_text("{ not json")
    with pytest.raises(ValueError, match=r"manifest\.json"):
        load_demonstrations(d)


def test_tampered_archive_with_valid_zip_is_checked_against_the_manifest(recorded, tmp_path):
    # a different but well-formed archive under the right hash: tick count must agree
    d = _copy(recorded, tmp_path / "d")
    rel = "object_bypass/demo_object_bypass_run_0.npz"
    _rewrite(d / rel, lambda a: a.update({k: a[k][:-1] for k in a if not k.startswith("cand")}))
    with zipfile.ZipFile(d / rel) as z:
        assert "t.npy" in z.namelist()
    _rehash(d, rel)
    with pytest.raises(ValueError, match=r"run_0\.npz"):
        load_demonstrations(d)


# ----------------------------------------------------------------------------- the CLI


def test_cli_records_and_shows(tmp_path, capsys):
    out = tmp_path / "cli"
    args = ["demonstrations", "record", "--task", "object_bypass", "--runs", "1"]
    main([*args, "--out", str(out), "--seed", "3"])
    assert (out / MANIFEST).is_file()
    assert (out / "object_bypass" / "demo_object_bypass_run_0.npz").is_file()
    capsys.readouterr()
    main(["demonstrations", "show", str(out), "--json"])
    summary = json.loads(capsys.readouterr().out)
    assert summary["runs"] == 1 and summary["seed"] == 3
    main(["demonstrations", "show", str(out)])
    assert "object_bypass" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--task", "teleporting"], "teleporting"),
        (["--task", "object_bypass", "--scene", "no_such_scene"], "no_such_scene"),
        (["--task", "doorway_crossing", "--scene", "demo_object_bypass"], "doorway"),
        (["--task", "object_bypass", "--runs", "0"], "--runs"),
    ],
)
def test_cli_bad_input_is_one_line_exit_2(tmp_path, capsys, args, needle):
    with pytest.raises(SystemExit) as exit_info:
        main(["demonstrations", "record", *args, "--out", str(tmp_path / "x")])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0]
    assert not (tmp_path / "x" / MANIFEST).exists()


def test_cli_show_of_a_bad_directory_is_one_line_exit_2(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["demonstrations", "show", str(tmp_path)])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "manifest.json" in err[0]
