"""The assistance measures of the in-the-loop recognition tally (issue 40), on hand-made
and random tick sequences: precision and coverage are shares, coverage is 0 without
assistance, no confident-wrong time when always right, the deciles split each trial's
labelled ticks, and a merged tally equals one tally of the concatenated ticks (the
per-trial deciles and longest episode excepted: those are summed and maximised)."""

from __future__ import annotations

import numpy as np
import pytest

from study.engine.recognition import CONFIDENT_BETA, DECILES, RecognitionTally

TABLE = {"la": "a", "lb": "b"}
DT = 0.05  # [s] a tick, as the trial loop's


def _rows(rng: np.random.Generator, n: int) -> list[tuple[str, str, str, str, float]]:
    """Random ticks ``(label, target, true_task, true_target, beta)``; a third of them
    unlabelled, beta often exactly at the threshold."""
    betas = [0.0, 0.3, CONFIDENT_BETA, 0.8, 1.0]
    out = []
    for _ in range(n):
        true_task = str(rng.choice(["a", "b", ""]))
        true_target = str(rng.choice(["x", "y"])) if true_task else ""
        out.append(
            (
                str(rng.choice(["la", "lb", "", "other"])),
                str(rng.choice(["x", "y", ""])),
                true_task,
                true_target,
                float(rng.choice(betas)),
            )
        )
    return out


def _tally(rows) -> RecognitionTally:
    return RecognitionTally(TABLE, dt_s=DT).add_rows(rows)


def test_the_measures_agree_with_a_direct_count(rng):
    rows = _rows(rng, 500)
    s = _tally(rows).summary()
    assisted = [r for r in rows if r[4] >= CONFIDENT_BETA]
    right = [r for r in assisted if r[2] and TABLE.get(r[0]) == r[2] and r[1] == r[3]]
    labelled = [r for r in rows if r[2]]
    wrong = [r for r in assisted if r[1] != r[3]]
    assert s["assist_precision"] == round(len(right) / len(assisted), 4)
    assert s["assist_unlabelled_ticks"] == sum(not r[2] for r in assisted)
    assert s["assist_precision_labelled"] == round(
        len(right) / sum(bool(r[2]) for r in assisted), 4
    )
    assert s["assist_coverage"] == round(
        sum(r[4] >= CONFIDENT_BETA for r in labelled) / len(labelled), 4
    )
    assert s["confident_wrong_s"] == pytest.approx(len(wrong) * DT, abs=1e-4)  # rounded to 4
    minutes = len(rows) * DT / 60.0
    assert s["confident_wrong_s_per_min"] == pytest.approx(len(wrong) * DT / minutes, abs=1e-4)
    for key in ("assist_precision", "assist_precision_labelled", "assist_coverage"):
        assert 0.0 <= s[key] <= 1.0


def test_the_longest_confident_wrong_episode_is_the_longest_run(rng):
    rows = _rows(rng, 400)
    run = longest = 0
    for r in rows:
        run = run + 1 if r[4] >= CONFIDENT_BETA and r[1] != r[3] else 0
        longest = max(longest, run)
    s = _tally(rows).summary()
    assert s["confident_wrong_longest_s"] == pytest.approx(longest * DT, abs=1e-4)
    assert s["confident_wrong_longest_s"] <= s["confident_wrong_s"] + 1e-9


def test_no_assistance_covers_nothing_and_is_never_wrong(rng):
    rows = [(*r[:4], float(rng.uniform(0.0, CONFIDENT_BETA * 0.999))) for r in _rows(rng, 200)]
    s = _tally(rows).summary()
    assert s["assist_coverage"] == 0.0
    assert s["assist_precision"] is None  # no assisted tick: undefined, not 0 or 1
    assert s["confident_wrong_s"] == 0.0 and s["confident_wrong_longest_s"] == 0.0


def test_always_right_assistance_is_precise_and_never_confidently_wrong(rng):
    rows = []
    for _ in range(300):
        task = str(rng.choice(["a", "b"]))
        target = str(rng.choice(["x", "y"]))
        rows.append((f"l{task}", target, task, target, float(rng.uniform(CONFIDENT_BETA, 1.0))))
    s = _tally(rows).summary()
    assert s["assist_precision"] == 1.0 and s["assist_coverage"] == 1.0
    assert s["confident_wrong_s"] == 0.0 and s["confident_wrong_s_per_min"] == 0.0
    assert s["loop_task_target_match"] == 1.0


def test_assistance_while_the_driver_does_nothing_is_wrong():
    rows = [("la", "x", "", "", 1.0)] * 3 + [("la", "x", "a", "x", 1.0)]
    s = _tally(rows).summary()
    assert s["assist_precision"] == 0.25 and s["assist_precision_labelled"] == 1.0
    assert s["assist_unlabelled_ticks"] == 3
    assert s["confident_wrong_s"] == pytest.approx(3 * DT)


def test_the_deciles_split_each_trial_and_sum_to_its_labelled_ticks(rng):
    rows = _rows(rng, int(rng.integers(1, 400)))
    s = _tally(rows).summary()
    deciles = s["deciles"]
    assert len(deciles) == DECILES
    for key in ("labelled_ticks", "task_matches", "task_target_matches"):
        assert sum(d[key] for d in deciles) == s[key]
    sizes = [d["labelled_ticks"] for d in deciles]
    n = s["labelled_ticks"]
    assert all(n // DECILES <= k <= -(-n // DECILES) for k in sizes)  # equal parts
    # the first decile holds the first labelled ticks in time order
    first = [r for r in rows if r[2]][: sizes[0]]
    assert deciles[0]["task_matches"] == sum(TABLE.get(r[0]) == r[2] for r in first)


def test_merged_tallies_equal_one_tally_of_the_concatenated_ticks(rng):
    trials = [_rows(rng, int(rng.integers(1, 200))) for _ in range(4)]
    whole = RecognitionTally(TABLE, dt_s=DT)
    for rows in trials:  # one tally, trial after trial
        for row in rows:
            whole.add(*row)
        whole.end_trial()
    merged = RecognitionTally({})
    for rows in trials:
        merged.merge(RecognitionTally.from_summary(_tally(rows).summary()))
    a, b = whole.summary(), merged.summary()
    floats = ("confident_wrong_s", "confident_wrong_s_per_min", "seconds")
    for key in a:
        if key == "assist":
            for k, v in a[key].items():
                assert b[key][k] == pytest.approx(v, abs=1e-6)  # sums of dt in another order
        elif key in floats:
            assert b[key] == pytest.approx(a[key], abs=1e-4)
        else:
            assert b[key] == a[key], key
    each = [_tally(rows).summary() for rows in trials]
    assert b["confident_wrong_longest_s"] == max(s["confident_wrong_longest_s"] for s in each)
    for k in range(DECILES):
        assert b["deciles"][k]["labelled_ticks"] == sum(
            s["deciles"][k]["labelled_ticks"] for s in each
        )


def test_a_summary_stored_before_the_assistance_measures_has_none():
    old = {
        "labelled_ticks": 2,
        "per_task": {
            "a": {"labelled_ticks": 2, "task_matches": 1, "task_target_matches": 1, "null_ticks": 0}
        },
    }
    s = RecognitionTally.from_summary(old).summary()
    assert s["labelled_ticks"] == 2 and s["loop_task_match"] == 0.5
    assert s["assist_precision"] is None and s["assist_coverage"] is None
    assert s["confident_wrong_s_per_min"] is None


def test_blend_weights_need_the_tick_duration():
    with pytest.raises(ValueError, match="dt_s"):
        RecognitionTally(TABLE).add("la", "x", "a", "x", 1.0)
