"""A model records its recipe, and rebuilding it from that recipe on any machine gives a
model that recognises as the original does (issue 36; docs/decisions.md,
"Reproducibility across machines"). `asa evaluate` runs on a model whose demonstrations
hash differently here than where it was made, and says so."""

from __future__ import annotations

import dataclasses
import json

import pytest

from autonomy.evaluation.agreement import recognition_agreement
from autonomy.model import DEFAULT_MODEL, load_model, save_model
from study.cli import main
from study.jobs.demonstrations import load_demonstrations
from study.jobs.evaluation import RECIPE, model_recipe
from study.jobs.training import recording_recipe

# The same CPU rebuilds the model bit for bit (agreement 1, differences 0). Another CPU's
# BLAS rounds the SOGP's fits apart by about 1e-6 relative (measured with OpenBLAS's
# Sandybridge kernels against its Haswell ones: docs/results.md, issue 36), which moves a
# blend weight by some 1e-5 and changes a winner only at a near-tie of two means. The
# promise: the same winner on at least 99 % of ticks, blend weights within 1e-3 on 99 %.
MIN_AGREEMENT = 0.99
MAX_BETA_P99 = 1e-3


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    out = tmp_path_factory.mktemp("recipe") / "demos"
    main(["demonstrations", "record", "--task", "all", "--runs", "1"]
         + ["--seed", "3", "--out", str(out)])  # fmt: skip
    return out


def test_the_recipe_is_read_from_the_manifest(tiny, tmp_path):
    assert recording_recipe(tiny) == {"task": "all", "runs": 1, "seed": 3}
    manifest = json.loads((tiny / "manifest.json").read_text())
    other = tmp_path / "other"
    other.mkdir()
    manifest["runs"][0]["seed"] = 4  # two calls with different seeds: no single recipe
    (other / "manifest.json").write_text(json.dumps(manifest))
    assert recording_recipe(other) is None
    assert recording_recipe(tmp_path / "missing") is None
    assert model_recipe({}) == RECIPE
    recipe = {"recipe": {"record": {"task": "all", "runs": 3, "seed": 1}}}
    assert model_recipe(recipe) == {"task": "all", "runs": 3, "seed": 1}


def test_asa_train_writes_the_recipe_and_compares(tiny, tmp_path, capsys):
    out = tmp_path / "m.npz"
    main(["train", "--demonstrations", str(tiny), "--out", str(out), "--seed", "5"]
         + ["--compare", str(DEFAULT_MODEL)])  # fmt: skip
    text = capsys.readouterr().out
    meta = load_model(out).metadata
    assert meta["recipe"] == {
        "record": {"task": "all", "runs": 1, "seed": 3},
        "train": {"seed": 5},
    }
    assert f"against {DEFAULT_MODEL} (other data" in text and "blend weights differ" in text
    model = load_model(out)
    demos = load_demonstrations(tiny)
    same = recognition_agreement(
        model, model, demos.cand_points, demos.cand_offsets, demos.u_norm, stride=3
    )
    assert same["winner_agreement"] == 1.0 and same["beta_difference"]["max"] == 0.0


def test_rebuilding_the_shipped_model_recognises_alike(tmp_path):
    shipped = load_model(DEFAULT_MODEL)
    recipe = model_recipe(shipped.metadata)
    train_seed = shipped.metadata.get("recipe", {}).get("train", {}).get("seed", 0)
    demos = tmp_path / "demos"
    main(["demonstrations", "record", "--task", recipe["task"], "--runs", str(recipe["runs"])]
         + ["--seed", str(recipe["seed"]), "--out", str(demos)])  # fmt: skip
    main(["train", "--demonstrations", str(demos), "--out", str(tmp_path / "m.npz")]
         + ["--seed", str(train_seed)])  # fmt: skip
    rebuilt = load_model(tmp_path / "m.npz")
    d = load_demonstrations(demos)
    found = recognition_agreement(rebuilt, shipped, d.cand_points, d.cand_offsets, d.u_norm)
    assert found["winner_agreement"] >= MIN_AGREEMENT, found
    assert found["beta_difference"]["p99"] <= MAX_BETA_P99, found


def test_asa_evaluate_runs_when_the_demonstrations_hash_otherwise(
    tiny, tmp_path, monkeypatch, capsys
):
    """A model whose demonstrations, recorded again here from its recipe, hash otherwise
    (as on a CPU that rounds differently): a warning naming both hashes, and a result."""
    monkeypatch.setenv("ASA_CACHE", str(tmp_path / "cache"))
    model = tmp_path / "m.npz"
    main(["train", "--demonstrations", str(tiny), "--out", str(model)])
    loaded = load_model(model)
    meta = {**loaded.metadata, "data_sha256": "f" * 64}  # as on the machine it was made on
    save_model(dataclasses.replace(loaded, metadata=meta), model)
    capsys.readouterr()  # the training's summary
    main(["evaluate", "--model", str(model), "--folds", "2", "--json", "--quiet"])
    captured = capsys.readouterr()
    warning = [line for line in captured.err.splitlines() if "warning" in line]
    assert len(warning) == 1 and "f" * 16 in warning[0] and "--runs 1 --seed 3" in warning[0]
    result = json.loads(captured.out)
    assert result["demonstrations"]["same_as_model"] is False
    assert result["demonstrations"]["model_data_sha256"] == "f" * 64
    assert result["demonstrations"]["data_sha256"] == loaded.metadata["data_sha256"]
    assert result["n_runs"] == 4 and result["folds"] == 2
