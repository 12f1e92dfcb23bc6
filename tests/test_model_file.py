"""The contextual-task model file (autonomy.model): exact round trip, and every kind of
corruption refused with a ValueError naming the file and the field."""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest

from autonomy.model import DEFAULT_MODEL, FORMAT_VERSION, load_model, model_arrays, save_model
from autonomy.training import TrainSettings, synthetic_demonstrations, train

FAST = TrainSettings(
    max_components=6, restarts=1, capacity=30, hyper_points=80, hyper_restarts=1, stride=3
)


@pytest.fixture(scope="module")
def model():
    q, task, run = synthetic_demonstrations(np.random.default_rng(5), runs=3, steps=30)
    return train(q, seed=2, settings=FAST, run=run, task=task)


@pytest.fixture
def saved(model, tmp_path):
    return save_model(model, tmp_path / "model.npz")


def _write(path, arrays):
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    path.write_bytes(buffer.getvalue())
    return path


def test_round_trip_is_exact(model, saved, rng):
    loaded = load_model(saved)
    a, b = model_arrays(model), model_arrays(loaded)
    assert a.keys() == b.keys()
    for name in a:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)
    Z = rng.normal(size=(25, 7))
    for x, y in zip(model.classifier.decision(Z), loaded.classifier.decision(Z), strict=True):
        np.testing.assert_array_equal(x, y)
    assert loaded.metadata["format_version"] == FORMAT_VERSION
    assert loaded.metadata["settings"]["capacity"] == FAST.capacity


def test_saving_twice_gives_the_same_bytes(model, tmp_path):
    a = save_model(model, tmp_path / "a.npz").read_bytes()
    b = save_model(model, tmp_path / "b.npz").read_bytes()
    assert a == b


def test_a_file_that_is_not_a_zip_is_refused(tmp_path):
    path = tmp_path / "junk.npz"
    path.write_bytes(b"this is not a model")
    with pytest.raises(ValueError, match="junk.npz.*not a readable"):
        load_model(path)


def test_a_truncated_file_is_refused(saved):
    data = saved.read_bytes()
    saved.write_bytes(data[: len(data) // 2])
    with pytest.raises(ValueError, match="model.npz"):
        load_model(saved)


def test_a_missing_file_is_named(tmp_path):
    with pytest.raises(ValueError, match="nothing.npz.*not found"):
        load_model(tmp_path / "nothing.npz")


@pytest.mark.parametrize(
    "field", ["cluster_means", "gmr_points", "scaler_scale", "sogp.0.alpha", "metadata"]
)
def test_a_missing_entry_is_named(model, tmp_path, field):
    arrays = model_arrays(model)
    del arrays[field]
    path = _write(tmp_path / "cut.npz", arrays)
    with pytest.raises(ValueError, match=rf"cut\.npz: field '{field}'"):
        load_model(path)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("cluster_means", np.zeros((1, 7))),
        ("cluster_covariances", np.zeros((2, 7, 6))),
        ("scaler_mean", np.zeros(6)),
        ("gmr_offsets", np.array([0, 1])),
        ("sogp.0.C_upper", np.zeros(3)),
        ("gmr_points", np.full((4, 5), np.nan)),
    ],
)
def test_a_wrong_shape_or_value_is_named(model, tmp_path, field, value):
    arrays = model_arrays(model)
    arrays[field] = value
    path = _write(tmp_path / "bad.npz", arrays)
    with pytest.raises(ValueError, match=rf"bad\.npz: field '{field}"):
        load_model(path)


def test_a_newer_format_version_is_refused(model, tmp_path):
    arrays = model_arrays(model)
    meta = json.loads(str(arrays["metadata"]))
    meta["format_version"] = FORMAT_VERSION + 1
    arrays["metadata"] = np.array(json.dumps(meta))
    path = _write(tmp_path / "new.npz", arrays)
    with pytest.raises(ValueError, match=r"new\.npz: field 'metadata.format_version'.*newer"):
        load_model(path)


def test_metadata_that_is_not_json_is_refused(model, tmp_path):
    arrays = model_arrays(model)
    arrays["metadata"] = np.array("{not json")
    path = _write(tmp_path / "meta.npz", arrays)
    with pytest.raises(ValueError, match=r"meta\.npz: field 'metadata'"):
        load_model(path)


def test_a_pickled_entry_is_refused(model, tmp_path):
    arrays = model_arrays(model)
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        for name, value in arrays.items():
            npy = io.BytesIO()
            obj = np.array([{"x": 1}], dtype=object) if name == "cluster_ids" else value
            np.lib.format.write_array(npy, obj, allow_pickle=True)
            archive.writestr(f"{name}.npy", npy.getvalue())
    path = tmp_path / "pickle.npz"
    path.write_bytes(buffer.getvalue())
    with pytest.raises(ValueError, match=r"pickle\.npz"):
        load_model(path)


def test_the_shipped_model_loads_and_is_small():
    model = load_model()
    assert model.n_clusters >= 2
    assert DEFAULT_MODEL.stat().st_size < 5e6  # the aim for a shipped model
    assert model.metadata["data_sha256"]


def test_an_older_feature_encoding_is_refused(model, tmp_path):
    # Version 1 encoded the angle as plain (cos, sin): its scaler and GPs live in another
    # feature space, so such a file must be retrained, not silently misread.
    arrays = model_arrays(model)
    meta = json.loads(str(arrays["metadata"]))
    meta["format_version"] = 1
    arrays["metadata"] = np.array(json.dumps(meta))
    path = _write(tmp_path / "old.npz", arrays)
    with pytest.raises(ValueError, match=r"old\.npz: field 'metadata.format_version'.*retrain"):
        load_model(path)


def test_the_shipped_model_is_small_and_current():
    assert DEFAULT_MODEL.stat().st_size < 5_000_000  # was 8.1 MB at capacity 500
    shipped = load_model()
    assert shipped.metadata["format_version"] == FORMAT_VERSION
    assert all(gp["basis"].shape[0] <= 250 for gp in shipped.sogp["models"])
