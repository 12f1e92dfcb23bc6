"""Training of the contextual-task model (autonomy.training, `asa train`): DP-GMM
clusters with tiny ones merged, labels used for reporting only, determinism for a seed."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from autonomy.model import model_arrays
from autonomy.training import (
    TrainSettings,
    format_summary,
    synthetic_demonstrations,
    train,
    way_points,
)
from study.cli import main

FAST = TrainSettings(
    max_components=8, restarts=2, capacity=40, hyper_points=100, hyper_restarts=1, stride=2
)


@pytest.fixture(scope="module")
def data():
    return synthetic_demonstrations(np.random.default_rng(11), runs=3, steps=40)


def _arrays(model):
    arrays = model_arrays(model)
    arrays.pop("metadata")
    return arrays


def test_training_is_deterministic_and_labels_are_for_reporting_only(data, seed):
    q, task, run = data
    with_labels = train(q, seed=seed, settings=FAST, run=run, task=task)
    without = train(q, seed=seed, settings=FAST, run=run)
    a, b = _arrays(with_labels), _arrays(without)
    assert a.keys() == b.keys()
    for name in a:
        np.testing.assert_allclose(a[name], b[name], rtol=1e-9, atol=1e-9, err_msg=name)
    clusters = with_labels.metadata["clusters"]
    assert "task_share" in clusters[0] and "task_share" not in without.metadata["clusters"][0]
    for entry in clusters:
        assert sum(entry["task_share"].values()) == pytest.approx(1.0, abs=1e-3)
    assert sum(e["size"] for e in clusters) == len(q)
    assert "primitive_0" in format_summary(with_labels)


def test_model_is_consistent_and_tiny_clusters_are_merged(data, seed):
    q, _, run = data
    settings = dataclasses.replace(FAST, min_cluster_share=0.2)
    model = train(q, seed=seed, settings=settings, run=run)
    sizes = np.diff(model.gmr_offsets)
    assert sizes.sum() == len(q)
    assert np.all(sizes >= 0.2 * len(q))  # every kept primitive is above the threshold
    assert np.all(np.diff(sizes) <= 0)  # numbered by decreasing size
    c = model.n_clusters
    assert model.cluster_means.shape == (c, 7)
    assert np.all(np.linalg.eigvalsh(model.cluster_covariances) > 0)
    np.testing.assert_array_equal(model.classifier.classes_, model.cluster_ids)
    meta = model.metadata
    assert meta["seed"] == seed and meta["n_points"] == len(q) and len(meta["data_sha256"]) == 64


def test_way_points_take_every_stride_th_tick_of_each_run():
    run = np.array([0, 0, 0, 0, 0, 1, 1, 1, 2])
    np.testing.assert_array_equal(way_points(9, run, 2), [0, 2, 4, 5, 7, 8])
    np.testing.assert_array_equal(way_points(9, None, 4), [0, 4, 8])


def test_bad_training_input_is_refused():
    with pytest.raises(ValueError, match="shape"):
        train(np.zeros((30, 5)))
    with pytest.raises(ValueError, match="finite"):
        train(np.full((30, 6), np.nan))
    with pytest.raises(ValueError, match="stride"):
        TrainSettings(stride=0)


def test_asa_train_refuses_missing_demonstrations(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(
            ["train", "--demonstrations", str(tmp_path / "none"), "--out", str(tmp_path / "m.npz")]
        )
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("asa: error:") and "none" in err and len(err.splitlines()) == 1


@pytest.mark.slow
def test_asa_train_reproduces_a_model_from_recorded_demonstrations(tmp_path):
    from autonomy.model import load_model

    demos = tmp_path / "demos"
    main(["demonstrations", "record", "--task", "all", "--runs", "2", "--seed", "3"]
         + ["--out", str(demos)])  # fmt: skip
    paths = []
    for k in range(2):
        out = tmp_path / f"m{k}.npz"
        main(["train", "--demonstrations", str(demos), "--out", str(out), "--seed", "5"])
        paths.append(out)
    a, b = (_arrays(load_model(p)) for p in paths)
    for name in a:
        np.testing.assert_allclose(a[name], b[name], rtol=1e-9, atol=1e-9, err_msg=name)
