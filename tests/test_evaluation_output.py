"""What `asa evaluate` shows (issue 16): progress, the introspection histograms and the
SOGP's entropy rank (thesis Fig. 7.25, Table 7.9), ACR and MICAD (Sec. 7.4.1)."""

from __future__ import annotations

import itertools
import json
import sys
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from autonomy.evaluation import (
    CORRESPONDENCE,
    METHODS,
    correspondence_rates,
    entropy_histogram,
    entropy_rank,
    evaluate,
    format_report,
    intra_cluster_dissimilarity,
    summarise_repeats,
    way_points_of,
)
from study.cli import main

sys.path.insert(0, str(Path(__file__).parent))
from test_evaluation import FAST, KINDS, synthetic_demos  # noqa: E402


def _test_points_of_pairs(demos, stride: int) -> int:
    """Way points of the task types outside each training pair, summed over pairs."""
    task = np.asarray(demos.task)[way_points_of(demos.run, stride)]
    types = sorted(set(task.tolist()))
    return sum(int(np.sum(~np.isin(task, p))) for p in itertools.combinations(types, 2))


@pytest.fixture(scope="module")
def demos():
    return synthetic_demos(np.random.default_rng(20261124), runs=2, steps=12)


@pytest.fixture(scope="module")
def traced(demos):
    """An evaluation whose jobs come back in reverse order, with its progress calls."""
    calls: list[tuple[int, int]] = []

    def reversed_map(fn, items):
        return reversed([fn(x) for x in items])

    result = evaluate(
        demos, kinds=KINDS, settings=replace(FAST, folds=2), map_fn=reversed_map,
        progress=lambda done, total: calls.append((done, total)),
    )  # fmt: skip
    return result, calls


def test_progress_is_called_once_per_job_with_rising_counts(traced, demos):
    result, calls = traced
    total = result["folds"] + len(list(itertools.combinations(KINDS, 2)))
    assert calls == [(done, total) for done in range(1, total + 1)]
    serial = evaluate(demos, kinds=KINDS, settings=replace(FAST, folds=2))
    same = [json.dumps({**r, "timings_s": None}, sort_keys=True) for r in (serial, result)]
    assert same[0] == same[1]  # results put back in job order


def test_histograms_count_every_test_point_of_every_pair(traced, demos):
    result, _ = traced
    n = _test_points_of_pairs(demos, FAST.stride)
    hist = result["introspection_histogram"]
    assert set(hist) == set(METHODS)
    for m in METHODS:
        assert hist[m]["edges"] == pytest.approx(np.linspace(0.0, 1.0, 11))
        assert sum(hist[m]["counts"]) == hist[m]["n"] == n
        assert all(c >= 0 for c in hist[m]["counts"]) and 0.0 <= hist[m]["median"] <= 1.0
    means = result["introspection_entropy"]
    rank = result["sogp_entropy_rank"]
    assert rank == 1 + sum(means[m] > means["sogp"] for m in METHODS)
    assert f"SOGP entropy rank: {rank} of 4" in format_report(result)
    for m in METHODS:
        pairs = result["introspection_micad_pairs"][m]
        assert set(pairs) == set(result["introspection_pairs"][m])
        assert all(v > 0 for v in pairs.values())
        assert result["introspection_micad"][m] == pytest.approx(np.mean(list(pairs.values())))
    # the kind-and-time belief: unseen at the same test points, seen at the scored ticks
    belief = result["kind_time_introspection"]
    assert belief["unseen"]["histogram"]["n"] == n
    assert belief["seen"]["histogram"]["n"] == result["n_test_ticks"]
    for side in ("seen", "unseen"):
        b = belief[side]
        assert sum(b["histogram"]["counts"]) == b["histogram"]["n"]
        for key in ("entropy", "decisive", "no_task"):
            assert 0.0 <= b[key] <= 1.0
    assert set(belief["unseen"]["pairs"]) == set(result["introspection_pairs"]["sogp"])
    text = format_report(result)
    assert "kind_time: normalised entropy" in text and "unseen" in text


def test_acr_is_the_mean_correspondence_rate_of_the_held_out_runs(traced, demos):
    result, _ = traced
    runs = {str(r) for r in np.unique(demos.run)}
    for m in CORRESPONDENCE:
        cr = result["correspondence_rates"][m]
        assert set(cr) == runs  # every run is held out once
        assert all(0.0 <= v <= 1.0 for v in cr.values())
        assert result["acr"][m] == pytest.approx(np.mean(list(cr.values())))
        assert result["micad"][m] > 0
    text = format_report(result)
    assert "ACR" in text and "MICAD" in text and "histogram" in text


def _only_candidate(demos, decoy_runs):
    """The demonstrations with one candidate per tick at the target's point: the target
    itself, or in ``decoy_runs`` another component."""
    n = len(demos.q)
    ids = np.where(np.isin(demos.run, decoy_runs), "decoy", demos.target)
    kinds = np.array([KINDS[t] for t in demos.task])
    return SimpleNamespace(
        **{k: getattr(demos, k) for k in ("q", "s", "u_norm", "run", "task", "target", "phase")},
        cand_offsets=np.arange(n + 1),
        cand_points=demos.s.copy(),
        cand_ids=ids,
        cand_kinds=kinds,
    )


def test_acr_is_one_where_the_target_is_the_only_candidate_and_zero_where_it_is_missing(demos):
    runs = np.unique(demos.run)
    decoy_runs = runs[::3]
    one = _only_candidate(demos, decoy_runs)
    result = evaluate(one, kinds=KINDS, settings=replace(FAST, folds=2, negatives=False))
    for m in CORRESPONDENCE:  # the classifiers' Eq. (5.8) winner and kind_time's belief
        cr = result["correspondence_rates"][m]
        assert all(cr[str(r)] == (0.0 if r in decoy_runs else 1.0) for r in runs)
        assert result["acr"][m] == pytest.approx(1.0 - len(decoy_runs) / len(runs))


def test_correspondence_rate_per_run(rng):
    run = rng.integers(0, 5, size=200)
    hit = rng.random(200) < 0.6
    cr = correspondence_rates(hit, run)
    assert list(cr) == [str(r) for r in np.unique(run)]
    for r, v in cr.items():
        assert v == np.count_nonzero(hit[run == int(r)]) / np.count_nonzero(run == int(r))
    assert set(correspondence_rates(np.ones(7, bool), np.zeros(7)).values()) == {1.0}
    with pytest.raises(ValueError, match="hit"):
        correspondence_rates(hit[:3], run)


def test_icad_is_the_mean_distance_to_the_assigned_clusters_points(rng):
    Z = rng.normal(size=(40, 7))
    y = rng.integers(0, 3, size=40)
    Q = rng.normal(size=(25, 7))
    assigned = rng.integers(0, 3, size=25)
    got = intra_cluster_dissimilarity(Q, Z, y, assigned)
    for i in range(len(Q)):
        members = Z[y == assigned[i]]
        want = np.mean([np.sqrt(np.sum((Q[i] - z) ** 2)) for z in members])
        assert got[i] == pytest.approx(want)
    single = intra_cluster_dissimilarity(Z[:1], Z[:1], np.array([7]), np.array([7]))
    assert single[0] == 0.0  # a query on its cluster's only point
    with pytest.raises(ValueError, match="no training point"):
        intra_cluster_dissimilarity(Q, Z, y, np.full(25, 9))


def test_entropy_histogram_and_rank(rng):
    h = np.concatenate((rng.random(100), [0.0, 1.0, 1.0]))
    hist = entropy_histogram(h)
    assert hist["counts"] == np.histogram(h, bins=10, range=(0.0, 1.0))[0].tolist()
    assert sum(hist["counts"]) == hist["n"] == 103 and hist["counts"][-1] >= 2
    assert hist["median"] == pytest.approx(np.median(h))
    assert entropy_histogram(np.zeros(0))["median"] is None
    assert entropy_rank({"sogp": 0.5, "svm": 0.7, "knn": 0.2, "rf": 0.5}) == 2
    assert entropy_rank({"sogp": 0.9, "svm": 0.7}) == 1
    assert entropy_rank({}) is None


def test_repeats_give_mean_and_sd_of_acr_and_micad(traced, rng):
    first, _ = traced
    other = json.loads(json.dumps({**first, "seed": first["seed"] + 1}))
    for key in ("acr", "micad", "introspection_entropy", "introspection_micad"):
        other[key] = {m: v + float(rng.normal(0.0, 0.1)) for m, v in other[key].items()}
    rep = summarise_repeats([first, other])
    for key in ("acr", "micad", "introspection_entropy", "introspection_micad"):
        for m in METHODS:
            pair = [first[key][m], other[key][m]]
            assert rep[f"{key}_mean"][m] == pytest.approx(np.mean(pair))
            assert rep[f"{key}_sd"][m] == pytest.approx(abs(pair[0] - pair[1]) / np.sqrt(2))
    assert rep["sogp_entropy_rank"] == entropy_rank(rep["introspection_entropy_mean"])
    text = format_report({**first, "repeats": rep})
    assert "over 2 seeds" in text and "ACR" in text and "entropy unseen" in text


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    out = tmp_path_factory.mktemp("evalout") / "demos"
    main(["demonstrations", "record", "--task", "all", "--runs", "1", "--seed", "4"]
         + ["--out", str(out)])  # fmt: skip
    return out


def test_asa_evaluate_prints_progress_on_stderr_and_clean_json(recorded, capsys):
    capsys.readouterr()
    argv = ["evaluate", "--demonstrations", str(recorded), "--folds", "2", "--json"]
    main([*argv, "--workers", "2"])
    captured = capsys.readouterr()
    result = json.loads(captured.out)  # stdout holds the JSON and nothing else
    total = 2 + 6  # folds + pairs of 4 task types
    lines = captured.err.strip().splitlines()
    assert [line.split(" jobs")[0] for line in lines] == [
        f"[evaluate] {k}/{total}" for k in range(1, total + 1)
    ]
    assert all("elapsed" in line for line in lines) and lines[-1].endswith("done")
    assert "left" in lines[0]
    for key in ("introspection_histogram", "acr", "micad", "sogp_entropy_rank"):
        assert key in result
    assert set(result["acr"]) == set(result["micad"]) == set(CORRESPONDENCE)
    assert "kind_time" in result["trajectory_rates"] and result["kind_time_introspection"]
    # every run of the shipped scenes gets its passages' normals (the axis cue)
    assert result["passage_normals"] == {"runs": 4, "of": 4}
