"""Offline evaluation of the recognisers (autonomy.evaluation, asa evaluate; thesis 7.2-7.4)."""

from __future__ import annotations

import json
import os
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from sklearn.metrics import fbeta_score

from autonomy.evaluation import (
    CORRESPONDENCE,
    METHODS,
    RECOGNISERS,
    EvaluationSettings,
    candidate_features,
    evaluate,
    f05_with_targets,
    fit_method,
    fit_prior,
    format_report,
    hard_negatives,
    replay_run,
    run_folds,
    summarise_repeats,
    way_points_of,
)
from autonomy.evaluation.folds import prepare_data
from autonomy.evaluation.kind_time import run_means, runs_of
from autonomy.features import FeatureScaler, task_features
from autonomy.kind_time import KindTimeRecogniser
from autonomy.training import synthetic_demonstrations
from study.cli import main

KINDS = {"doorway_crossing": "doorway", "object_inspection": "object", "wall_following": "wall"}
FAST = EvaluationSettings(
    folds=3,
    capacity=30,
    hyper_points=40,
    hyper_restarts=1,
    rf_trees=8,
    stride=3,
    test_stride=3,
    inner_folds=2,
    sogp_length_scale_grid=(),
    sogp_claim_grid=(0.0,),
    # the toy patterns are scored with the 0.5-std cap of earlier versions: uncapped (the
    # shipped bound) the SOGP's macro F0.5 on them falls to about .46 (docs/results.md)
    max_length_scale=0.5,
)


def synthetic_demos(rng: np.random.Generator, runs: int = 4, steps: int = 30):
    """Synthetic demonstrations with candidates: the demonstrated target plus two
    distractors of other kinds per tick (ids fixed per run); the first third of every
    run approaches its target, the rest executes the task."""
    q, task, run = synthetic_demonstrations(rng, runs=runs, steps=steps)
    first = np.r_[0, np.flatnonzero(np.diff(run)) + 1]
    step = np.arange(len(run)) - first[np.searchsorted(first, np.arange(len(run)), "right") - 1]
    kinds = list(KINDS.values())
    points, ids, ckinds, offsets, target = [], [], [], [0], []
    shift = {r: rng.uniform(-2.5, 2.5, size=(2, 2)) for r in np.unique(run)}
    for i in range(len(q)):
        kind = KINDS[task[i]]
        others = [k for k in kinds if k != kind]
        s = q[i, :2]
        cands = [(f"{kind}_{run[i]}", kind, s)]
        for j, k in enumerate(others):
            cands.append((f"{k}_{run[i]}", k, s + shift[run[i]][j]))
        order = rng.permutation(len(cands))  # the recorder's order is the scene's
        for j in order:
            ids.append(cands[j][0])
            ckinds.append(cands[j][1])
            points.append(cands[j][2])
        offsets.append(offsets[-1] + len(cands))
        target.append(cands[0][0])
    return SimpleNamespace(
        q=q,
        s=q[:, :2].copy(),
        u_norm=q[:, 3:6].copy(),
        run=run,
        task=task,
        target=np.array(target),
        phase=np.where(step < steps // 3, "approach", "execute"),
        cand_offsets=np.array(offsets),
        cand_points=np.array(points),
        cand_ids=np.array(ids),
        cand_kinds=np.array(ckinds),
    )


@pytest.fixture(scope="module")
def result():
    return evaluate(_result_demos(), kinds=KINDS, settings=FAST, model="synthetic")


def _result_demos():
    seed = int(os.environ.get("ASA_TEST_SEED", "20261123"))  # the conftest's seed, once
    return synthetic_demos(np.random.default_rng(seed), runs=3, steps=25)


def test_candidate_features_equal_task_features_tick_by_tick(rng):
    demos = synthetic_demos(rng, runs=1, steps=10)
    q, tick = candidate_features(demos.cand_points, demos.cand_offsets, demos.u_norm)
    for i in range(len(demos.q)):
        a, b = demos.cand_offsets[i], demos.cand_offsets[i + 1]
        np.testing.assert_allclose(q[a:b], task_features(demos.cand_points[a:b], demos.u_norm[i]))
        assert np.all(tick[a:b] == i)


def test_folds_split_runs_never_ticks_and_hold_every_task(rng):
    runs = 4 * rng.integers(2, 6)
    run_task = np.array(["a", "b", "c", "d"] * (runs // 4))
    folds = int(rng.integers(2, runs // 4 + 1))
    fold = run_folds(run_task, folds, rng)
    assert fold.shape == (runs,) and set(fold.tolist()) == set(range(folds))
    for k in range(folds):  # stratified: every task type in every fold
        assert set(run_task[fold == k]) == {"a", "b", "c", "d"}
    # ticks inherit their run's fold, so a run is never split
    run = np.repeat(np.arange(runs), rng.integers(1, 9, size=runs))
    tick_fold = fold[run]
    for r in range(runs):
        assert len(set(tick_fold[run == r].tolist())) == 1
    wp = way_points_of(run, 3)
    for r in range(runs):
        rows = np.flatnonzero(run == r)
        np.testing.assert_array_equal(wp[np.isin(wp, rows)], rows[::3])


def test_f05_needs_the_right_target(rng):
    labels = ["a", "b", "c"]
    t = rng.choice(labels, size=200)
    p = np.where(rng.random(200) < 0.7, t, rng.choice(labels, size=200))
    ok = np.ones(200, dtype=bool)
    got = f05_with_targets(t, p, ok, labels)
    ref = fbeta_score(t, p, beta=0.5, labels=labels, average=None, zero_division=0)
    np.testing.assert_allclose([got[c] for c in labels], ref)
    assert got["macro"] == pytest.approx(np.mean(ref))
    # the right type at a wrong target is a false positive and a false negative
    ok[:50] = False
    worse = f05_with_targets(t, p, ok, labels)
    assert all(worse[c] <= got[c] for c in labels)
    assert f05_with_targets(["a"], ["a"], [False], ["a"])["a"] == 0.0


def test_evaluation_result_has_the_documented_shape(result):
    labels = sorted(KINDS)
    assert result["labels"] == labels and result["folds"] == FAST.folds
    assert result["n_runs"] == 9 and result["model"] == "synthetic"
    for m in METHODS:
        f = result["f05"][m]
        assert set(f) == {*labels, "macro"}
        assert all(0.0 <= v <= 1.0 for v in f.values())
        conf = np.array(result["confusion"][m]["matrix"])
        assert conf.shape == (3, 4) and conf.sum() == result["n_test_ticks"]
        pairs = result["introspection_pairs"][m]
        assert set(pairs) == {
            "doorway_crossing+object_inspection",
            "doorway_crossing+wall_following",
            "object_inspection+wall_following",
        }
        assert all(0.0 <= v <= 1.0 for v in pairs.values())
        mean = result["introspection_entropy"][m]  # issue 3: classifier -> a number
        assert isinstance(mean, float) and mean == pytest.approx(np.mean(list(pairs.values())))
    assert set(result["f05"]) == set(METHODS) == set(result["introspection_entropy"])
    assert result["negatives"] is True
    assert result["sogp_length_scale_cap"] == [FAST.max_length_scale] * FAST.folds
    first = FAST.sogp_claim_grid[0]  # per fold, the threshold of every task type
    assert result["sogp_claim_threshold"] == [dict.fromkeys(labels, first)] * FAST.folds
    assert set(result["sogp_at_least_baselines"]) == {*labels, "macro"}
    assert set(result["trajectory_rates"]) == set(RECOGNISERS)
    for rates in result["trajectory_rates"].values():
        assert sum(rates.values()) == pytest.approx(1.0)
    json.dumps(result)  # plain JSON types
    text = format_report(result)
    assert "F0.5" in text and "introspection" in text and "bayes_filter" in text


def test_the_sogp_recognises_synthetic_tasks_and_targets_well(result):
    # Three well-separated synthetic patterns, distractors 0-3.5 m off the target.
    assert result["f05"]["sogp"]["macro"] > 0.6
    assert result["trajectory_rates"]["sogp"]["success"] > 0.5


def test_kind_time_is_reported_beside_the_sogp(result):
    assert set(result["acr"]) == set(result["micad"]) == set(CORRESPONDENCE)
    cr = result["correspondence_rates"]
    assert set(cr) == set(CORRESPONDENCE) and set(cr["kind_time"]) == set(cr["sogp"])
    assert all(0.0 <= v <= 1.0 for v in cr["kind_time"].values())
    assert result["acr"]["kind_time"] == pytest.approx(np.mean(list(cr["kind_time"].values())))
    assert result["micad"]["kind_time"] > 0.0
    rates = result["trajectory_rates"]["kind_time"]
    assert all(0.0 <= v <= 1.0 for v in rates.values()) and sum(rates.values()) == 1.0
    for side in ("seen", "unseen"):
        belief = result["kind_time_introspection"][side]
        assert 0.0 <= belief["entropy"] <= 1.0 and 0.0 <= belief["decisive"] <= 1.0
        assert 0.0 <= belief["no_task"] <= 1.0
    text = format_report(result)
    acr_line = next(line for line in text.splitlines() if line.startswith("ACR "))
    assert len(acr_line.split()) == 1 + len(CORRESPONDENCE)
    assert "kind_time" in text.split("trajectory rates")[1]
    # three well-separated patterns, two distractors per tick: a random pick is right on
    # a third of the ticks; the most believed candidate is the target on most of them
    assert result["acr"]["kind_time"] > 0.5


def test_a_folds_intent_prior_sees_only_its_training_runs(rng, monkeypatch):
    import autonomy.evaluation.jobs as jobs
    import autonomy.evaluation.kind_time as kt

    demos = synthetic_demos(rng, runs=2, steps=12)
    fold_calls, pair_calls, current = [], [], {}
    real_fold, real_prior = jobs.kind_time_fold, kt.demonstrated_prior

    def fold_spy(data, k, *args):
        current["held_out"] = set(np.unique(data.run[data.fold == k]).tolist())
        current["training_ticks"] = int(np.sum(data.fold != k))
        try:
            return real_fold(data, k, *args)
        finally:
            current.clear()

    def prior_spy(q, labels, candidates, executing):
        runs = {int(str(i).rsplit("_", 1)[1]) for i in candidates.ids}  # ids name the run
        if current:
            fold_calls.append((runs, len(q), dict(current)))
        else:
            pair_calls.append((runs, set(np.asarray(labels).tolist())))
        return real_prior(q, labels, candidates, executing)

    monkeypatch.setattr(jobs, "kind_time_fold", fold_spy)
    monkeypatch.setattr(kt, "demonstrated_prior", prior_spy)
    evaluate(demos, kinds=KINDS, settings=FAST)
    every = set(np.unique(demos.run).tolist())
    assert len(fold_calls) == FAST.folds and len(pair_calls) == 3
    for runs, n, fold in fold_calls:  # every tick of the training runs, none held out
        assert runs.isdisjoint(fold["held_out"]) and runs | fold["held_out"] == every
        assert n == fold["training_ticks"] == np.isin(demos.run, list(runs)).sum()
    held_out = sorted(r for _, _, fold in fold_calls for r in fold["held_out"])
    assert held_out == sorted(every)  # each run held out by one fold
    task_of = {int(r): demos.task[demos.run == r][0] for r in every}
    for runs, labels in pair_calls:  # introspection: the pair's task types only
        assert len(labels) == 2 and len({task_of[r] for r in runs}) == 2


def test_kind_time_replay_names_only_the_ticks_candidates_and_decays_when_idle(rng):
    demos = synthetic_demos(rng, runs=2, steps=20)
    idle = np.zeros(len(demos.q), dtype=bool)
    for r in np.unique(demos.run):  # the driver lets go of the stick for 5 ticks a run
        start = np.flatnonzero(demos.run == r)[10]
        idle[start : start + 5] = True
    demos.u_norm[idle] = 0.0
    data = prepare_data(demos, kinds=KINDS, settings=FAST, fold_rng=rng)
    train = np.flatnonzero(data.fold != 0)
    scaler = FeatureScaler().fit(data.X_true[train])
    sogp = fit_method(
        "sogp", scaler.transform(data.X_true[train]), data.y[train], data.run[train],
        settings=FAST, rng=rng, tune=False,
    )  # fmt: skip
    rec = KindTimeRecogniser(fit_prior(data, train, sogp.classes), FAST.kind_time)
    Z = scaler.transform(data.X_cand)
    for ticks in runs_of(data, np.flatnonzero(data.fold == 0)):
        replay = replay_run(rec, run_means(sogp.model, Z, data, ticks), data, ticks)
        for n, i in enumerate(ticks):
            assert replay.row[n] == -1 or data.off[i] <= replay.row[n] < data.off[i + 1]
        assert set(replay.col.tolist()) <= {-1, *range(len(sogp.classes))}
        assert np.all((replay.entropy >= 0) & (replay.entropy <= 1))
        assert np.all((replay.no_task >= 0) & (replay.no_task <= 1))
        still = idle[ticks]
        assert np.all(replay.col[still] == -1) and not replay.decisive[still].any()
        # Eq. (4.14) alone mixes the belief with the uniform: its entropy never falls
        h = replay.entropy[still]
        assert np.all(np.diff(h) >= -1e-12) and h[-1] > replay.entropy[np.argmax(still) - 1]


def test_repeats_summarise_the_f05_over_seeds(result):
    other = evaluate(_result_demos(), kinds=KINDS, settings=replace(FAST, seed=FAST.seed + 1))
    rep = summarise_repeats([result, other])
    assert rep["seeds"] == [FAST.seed, FAST.seed + 1]
    for m in METHODS:
        for c, mean in rep["f05_mean"][m].items():
            pair = [result["f05"][m][c], other["f05"][m][c]]
            assert mean == pytest.approx(np.mean(pair))
            assert rep["f05_sd"][m][c] == pytest.approx(abs(pair[0] - pair[1]) / np.sqrt(2))
    for c, share in rep["sogp_at_least_baselines"].items():
        wins = [result["sogp_at_least_baselines"][c], other["sogp_at_least_baselines"][c]]
        assert share == sum(wins) / 2
    for rates in rep["trajectory_rates_mean"].values():
        assert sum(rates.values()) == pytest.approx(1.0)
    one = summarise_repeats([result])
    assert one["f05_mean"] == result["f05"] and all(
        v == 0.0 for sd in one["f05_sd"].values() for v in sd.values()
    )
    text = format_report({**result, "repeats": rep})
    assert "over 2 seeds" in text and "+-" in text
    with pytest.raises(ValueError, match="at least one"):
        summarise_repeats([])


def test_bad_settings_are_refused(rng):
    with pytest.raises(ValueError, match="folds: must be an integer >= 2"):
        EvaluationSettings(folds=1)
    with pytest.raises(ValueError, match="sogp_length_scale_grid"):
        EvaluationSettings(sogp_length_scale_grid=(0.5, 0.0))
    with pytest.raises(ValueError, match="negatives_per_tick"):
        EvaluationSettings(negatives_per_tick=0)
    for claims in ((), (0.0, 1.5), (float("nan"),)):
        with pytest.raises(ValueError, match="sogp_claim_grid"):
            EvaluationSettings(sogp_claim_grid=claims)
    demos = synthetic_demos(rng, runs=1, steps=10)
    with pytest.raises(ValueError, match=r"folds: must be between 2 and the number of runs"):
        evaluate(demos, kinds=KINDS, settings=EvaluationSettings(folds=4))
    one = synthetic_demos(rng, runs=1, steps=10)
    keep = one.task == "wall_following"
    for name in ("q", "s", "u_norm", "run", "task", "target"):
        setattr(one, name, getattr(one, name)[keep])
    with pytest.raises(ValueError, match="at least 2 task types"):
        evaluate(one, kinds=KINDS, settings=FAST, where="one_type")


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    out = tmp_path_factory.mktemp("eval") / "demos"
    main(["demonstrations", "record", "--task", "all", "--runs", "1", "--seed", "4"]
         + ["--out", str(out)])  # fmt: skip
    return out


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--demonstrations", "{tmp}/none"], "none"),
        (["--demonstrations", "{demos}", "--folds", "1"], "--folds"),
        (["--demonstrations", "{demos}", "--folds", "5"], "--folds: must be between 2"),
        (["--demonstrations", "{demos}", "--model", "{tmp}/bad.npz"], "bad.npz"),
        (["--model", "{tmp}/bad.npz"], "bad.npz"),  # no demonstrations: nothing recorded
        (["--demonstrations", "{demos}", "--workers", "0"], "--workers"),
        (["--demonstrations", "{demos}", "--repeats", "0"], "--repeats: must be at least 1"),
    ],
)
def test_asa_evaluate_bad_input_is_one_line_and_exit_2(args, needle, recorded, tmp_path, capsys):
    (tmp_path / "bad.npz").write_bytes(b"not a model")
    argv = [a.format(tmp=tmp_path, demos=recorded) for a in args]
    with pytest.raises(SystemExit) as exit_info:
        main(["evaluate", *argv])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("asa: error:") and needle in err and len(err.splitlines()) == 1


def test_sogp_length_scale_cap_is_chosen_by_inner_cv_on_the_training_data(rng):
    demos = synthetic_demos(rng, runs=2, steps=20)
    label = {c: i for i, c in enumerate(sorted(KINDS))}
    y = np.array([label[t] for t in demos.task])
    Z = (demos.q - demos.q.mean(axis=0)) / demos.q.std(axis=0)
    Z = np.column_stack((Z[:, :2], np.cos(demos.q[:, 2]), np.sin(demos.q[:, 2]), Z[:, 3:]))
    grid = (0.3, 3.0)
    settings = replace(FAST, sogp_length_scale_grid=grid)
    neg = Z[::3] + rng.normal(0.0, 2.0, size=Z[::3].shape)  # no task lies there
    fitted = fit_method(
        "sogp", Z, y, demos.run, settings=settings, rng=rng, negatives=neg,
        negative_groups=demos.run[::3],
    )  # fmt: skip
    assert fitted.model.max_length_scale in grid


def test_sogp_claim_thresholds_are_chosen_by_inner_cv_and_only_remove_claims(rng):
    demos = synthetic_demos(rng, runs=2, steps=20)
    label = {c: i for i, c in enumerate(sorted(KINDS))}
    y = np.array([label[t] for t in demos.task])
    Z = (demos.q - demos.q.mean(axis=0)) / demos.q.std(axis=0)
    claims = (0.0, 0.3, 0.6)
    settings = replace(FAST, sogp_claim_grid=claims)
    neg = Z[::3] + rng.normal(0.0, 2.0, size=Z[::3].shape)
    fitted = fit_method(
        "sogp", Z, y, demos.run, settings=settings, rng=rng, negatives=neg,
        negative_groups=demos.run[::3],
    )  # fmt: skip
    assert fitted.claim.shape == (len(KINDS),)  # one threshold per task type
    assert set(fitted.claim.tolist()) <= set(claims)
    queries = np.concatenate((Z, neg))
    means = fitted.model.scores(queries)
    fitted.claim = np.zeros(len(KINDS))
    low = fitted.task_scores(queries)
    assert np.array_equal(~np.isnan(low), means >= 0.0)  # Eq. (5.10): confidence >= 1/2
    for j in range(len(KINDS)):  # raising one class's threshold removes only its claims
        fitted.claim = np.zeros(len(KINDS))
        fitted.claim[j] = 0.6
        high = fitted.task_scores(queries)
        assert np.array_equal(~np.isnan(high[:, j]), means[:, j] >= 0.6)
        others = np.arange(len(KINDS)) != j
        np.testing.assert_array_equal(high[:, others], low[:, others])


def test_the_result_does_not_depend_on_how_the_jobs_are_run(rng):
    from concurrent.futures import ThreadPoolExecutor

    demos = synthetic_demos(rng, runs=3, steps=12)
    serial = evaluate(demos, kinds=KINDS, settings=FAST)
    with ThreadPoolExecutor(2) as pool:  # jobs in another order, interleaved
        pooled = evaluate(demos, kinds=KINDS, settings=FAST, map_fn=pool.map)
    serial.pop("timings_s")
    pooled.pop("timings_s")
    assert json.dumps(serial, sort_keys=True) == json.dumps(pooled, sort_keys=True)


def test_hard_negatives_are_other_candidates_of_the_same_tick(rng):
    demos = synthetic_demos(rng, runs=1, steps=12)
    off, ids = demos.cand_offsets, demos.cand_ids
    ticks = np.arange(0, len(demos.q), 2)
    per_tick = int(rng.integers(1, 3))
    rows = hard_negatives(ticks, off, ids, demos.target, per_tick, rng)
    tick_of = np.repeat(np.arange(len(off) - 1), np.diff(off))
    assert set(tick_of[rows].tolist()) == set(ticks.tolist())  # every tick gives some
    assert np.all(ids[rows] != demos.target[tick_of[rows]])  # never the demonstrated one
    assert np.all(np.bincount(tick_of[rows]) <= per_tick)


def test_cache_records_once_and_reports_another_hash(recorded, tmp_path, monkeypatch):
    from autonomy.training import data_sha256
    from study.jobs.demonstrations import load_demonstrations
    from study.jobs.evaluation import cache_root, cached_demonstrations

    monkeypatch.setenv("ASA_CACHE", str(tmp_path / "cache"))
    assert cache_root() == tmp_path / "cache"
    sha = data_sha256(load_demonstrations(recorded).q)  # the fixture: 1 run per task, seed 4
    folder, fresh, mismatch = cached_demonstrations(sha, runs=1, seed=4)
    assert fresh and mismatch is None and folder == tmp_path / "cache" / sha[:16]
    assert [p.name for p in (tmp_path / "cache").iterdir()] == [sha[:16]]  # no leftovers
    again, fresh_again, mismatch = cached_demonstrations(sha, runs=1, seed=4)
    assert again == folder and not fresh_again and mismatch is None  # from the cache
    # a model made on a CPU that rounds otherwise: recorded, kept, used, and reported
    other, fresh, mismatch = cached_demonstrations("0" * 64, runs=1, seed=4, where="m.npz")
    assert fresh and other == tmp_path / "cache" / ("0" * 16)
    assert (mismatch.got, mismatch.expected, mismatch.recorded) == (sha, "0" * 64, True)
    line = mismatch.text(flags=True)
    assert "m.npz" in line and sha[:16] in line and "0" * 16 in line and "--runs 1" in line
    _, fresh, mismatch = cached_demonstrations("0" * 64, runs=1, seed=4, where="m.npz")
    assert not fresh and mismatch.got == sha  # not recorded again
    (folder.parent / ("1" * 16)).symlink_to(folder)  # a cache that holds other data
    _, fresh, mismatch = cached_demonstrations("1" * 64, where="m.npz")
    assert not fresh and "cached in" in mismatch.text()
    monkeypatch.delenv("ASA_CACHE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_root() == tmp_path / "xdg" / "asa-study"


def test_passage_normals_come_from_the_runs_scenes(recorded):
    from study.jobs.demonstrations import candidate_normals, load_demonstrations

    demos = load_demonstrations(recorded)
    normals, missing = candidate_normals(demos)
    assert missing == [] and normals.shape == demos.cand_points.shape
    passage = np.isin(demos.cand_kinds, ("doorway", "gap", "dock"))
    assert passage.any()
    # unit crossing directions, rotated only (1e-12: a few roundings of cos and sin)
    np.testing.assert_allclose(np.hypot(*normals[passage].T), 1.0, atol=1e-12)
    assert not normals[~passage].any()  # objects and walls have none
    # another scene of the run's name, or none shipped: its runs keep zero normals
    runs = [{**r, "scene": "cluttered_room"} for r in demos.runs[:1]] + [
        {**r, "scene": "not_a_shipped_scene"} for r in demos.runs[1:]
    ]
    other, missing = candidate_normals(replace(demos, runs=tuple(runs)))
    assert missing == ["cluttered_room"] + ["not_a_shipped_scene"] * (len(runs) - 1)
    assert not other.any()


@pytest.mark.slow
def test_asa_evaluate_runs_on_recorded_demonstrations(recorded, tmp_path, capsys):
    out = tmp_path / "eval.json"
    main(["evaluate", "--demonstrations", str(recorded), "--folds", "2", "--json"]
         + ["--repeats", "2", "--out", str(out), "--quiet"])  # fmt: skip
    captured = capsys.readouterr()
    printed = json.loads(captured.out)
    saved = json.loads(out.read_text())
    assert printed == saved and captured.err == ""  # --quiet: no progress lines
    for key in ("f05", "confusion", "introspection_entropy", "trajectory_rates"):
        assert key in saved
    assert saved["n_runs"] == 4 and saved["folds"] == 2 and saved["seed"] == 0
    assert saved["passage_normals"] == {"runs": 4, "of": 4} and "kind_time" in saved["acr"]
    assert saved["repeats"]["seeds"] == [0, 1]  # the top level is the first seed's
