"""Exponential baseline recogniser (thesis Eqs. 7.4, 7.5) and its tuning."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from autonomy.baseline_recogniser import (
    ExponentialBaseline,
    ExponentialScales,
    ExponentialSettings,
    LabelledTicks,
    alpha_beta,
    baseline_confidence,
    tune_exponential,
)

KINDS = {"doorway_crossing": "doorway", "wall_following": "wall", "object_inspection": "object"}


@settings(max_examples=50, deadline=None)
@given(
    st.floats(0.0, 10.0),  # alpha [m]
    st.floats(0.0, np.pi),  # beta [rad]
    st.floats(0.01, 3.0),  # k_alpha: the exponent stays far from underflow
    st.floats(0.01, 3.0),
    st.sampled_from(["product", "sum"]),
)
def test_confidence_in_unit_interval_and_monotone(
    alpha: float, beta: float, ka: float, kb: float, combine: str
) -> None:
    sc = ExponentialScales(k_alpha=ka, k_beta=kb)

    def c(a: float, b: float) -> float:
        return float(baseline_confidence(np.array([a]), np.array([b]), sc, combine=combine)[0])

    c0 = c(alpha, beta)
    assert 0.0 < c0 <= 1.0
    assert c(alpha + 0.5, beta) <= c0 and c(alpha, beta + 0.2) <= c0
    if combine == "sum" or beta > 1e-3:  # strictly, unless the other factor is 0
        assert c(alpha + 0.5, beta) < c0
    if combine == "sum" or alpha > 1e-3:
        assert c(alpha, beta + 0.2) < c0


@settings(max_examples=50, deadline=None)
@given(
    st.floats(0.05, 5.0),
    st.floats(-np.pi, np.pi),
    st.floats(-np.pi, np.pi),
    st.booleans(),
)
def test_alpha_beta_ranges(d: float, psi: float, u_angle: float, tangent: bool) -> None:
    p = d * np.array([[np.cos(psi), np.sin(psi)]])
    u = np.array([np.cos(u_angle), np.sin(u_angle), 0.0])
    a, b = alpha_beta(p, u, tangent=tangent, psi_ref=np.pi / 2)
    assert a[0] == pytest.approx(d)
    if tangent:  # v_smin = |sin(theta)|: input along the tangent gives beta = 0
        assert b[0] == pytest.approx(1.0 - abs(np.sin(u_angle - psi)), abs=1e-9)
    else:
        assert b[0] == pytest.approx(abs(abs(psi) - np.pi / 2), abs=1e-9)


UNIT = {t: ExponentialScales(psi_ref=np.pi / 2 if k == "wall" else 0.0) for t, k in KINDS.items()}


def test_decision_null_and_forms() -> None:
    base = ExponentialBaseline(KINDS, settings=ExponentialSettings(scales=UNIT, threshold=0.3))
    cands = [
        ("door_ahead", "doorway", np.array([2.0, 0.2])),
        ("door_side", "doorway", np.array([0.5, 2.0])),
        ("wall", "wall", np.array([3.0, 0.1])),  # wall dead ahead: beta ~ 90 deg
    ]
    out = base.step(cands, np.zeros(3))
    assert out.decision == ("doorway_crossing", "door_ahead")
    assert out.confidence == pytest.approx(
        np.exp(-np.hypot(2.0, 0.2) * np.arctan2(0.2, 2.0)), rel=1e-6
    )
    out = base.step([("wall", "wall", np.array([0.0, -0.7]))], np.zeros(3))  # abeam: c = 1
    assert out.decision == ("wall_following", "wall") and out.confidence == pytest.approx(1.0)
    strict = ExponentialBaseline(KINDS, settings=ExponentialSettings(scales=UNIT, threshold=0.99))
    assert strict.step(cands, np.zeros(3)).decision is None
    assert strict.step([], np.zeros(3)).decision is None
    assert ExponentialBaseline(KINDS).threshold_ == 0.4  # the form's default
    # Eq. (7.4): an object straight ahead, the input sideways along its surface, c = 1;
    # Eq. (7.5) scores the same object by the heading, also 1: the input tells them apart.
    obj = [("obj", "object", np.array([1.0, 0.0]))]
    theta = ExponentialBaseline(KINDS, settings=ExponentialSettings(form="theta"))
    assert theta.step(obj, np.array([0.0, 1.0, 0.0])).confidence == pytest.approx(1.0)
    assert theta.step(obj, np.array([1.0, 0.0, 0.0])).confidence < 1.0
    for bad, match in (
        ({"form": "max"}, "form"),
        ({"combine": "max"}, "combine"),
        ({"threshold": 1.5}, "threshold"),
        ({"scales": {"x": ExponentialScales()}}, "unknown task"),
    ):
        with pytest.raises(ValueError, match=match):
            ExponentialBaseline(KINDS, settings=ExponentialSettings(**bad))


def _two_doorways(rng: np.random.Generator, n_runs: int = 4, n: int = 40) -> LabelledTicks:
    """Runs towards doorway ``a`` (ahead, sometimes farther) with a decoy ``b`` nearer
    but off to the side, and a wall ahead-left: the target is always ``a``."""
    points, ids, kinds, off, u, run = [], [], [], [0], [], []
    for r in range(n_runs):
        for _ in range(n):
            da, db = rng.uniform(1.0, 4.0), rng.uniform(0.3, 1.0)
            pa = da * np.array([1.0, rng.normal(0.0, 0.02)])
            pb = db * np.array([np.cos(1.0), np.sin(1.0)])
            pw = rng.uniform(0.5, 2.0) * np.array([np.cos(0.6), np.sin(0.6)])
            points += [pa, pb, pw]
            ids += ["a", "b", "w"]
            kinds += ["doorway", "doorway", "wall"]
            off.append(off[-1] + 3)
            u.append([1.0, 0.0, 0.0])
            run.append(r)
    m = len(run)
    return LabelledTicks(
        points=np.array(points),
        offsets=np.array(off),
        ids=np.array(ids),
        kinds=np.array(kinds),
        u=np.array(u),
        task=np.full(m, "doorway_crossing"),
        target=np.full(m, "a"),
        run=np.array(run),
    )


@pytest.mark.parametrize("form", ["psi", "theta"])
def test_tuning_recognises_the_constant_target(form: str) -> None:
    ticks = _two_doorways(np.random.default_rng(3))
    tuned = tune_exponential(ticks, kinds=KINDS, form=form)
    assert tuned.form == form and set(tuned.scales) == set(KINDS)
    base = ExponentialBaseline(KINDS, settings=tuned)
    hits = 0
    for i in range(len(ticks.run)):
        a, b = ticks.offsets[i], ticks.offsets[i + 1]
        cands = [(ticks.ids[j], ticks.kinds[j], ticks.points[j]) for j in range(a, b)]
        hits += base.step(cands, ticks.u[i]).decision == ("doorway_crossing", "a")
    assert hits / len(ticks.run) > 0.95


def test_tuning_is_deterministic_and_validates() -> None:
    ticks = _two_doorways(np.random.default_rng(5), n_runs=3, n=20)
    assert tune_exponential(ticks, kinds=KINDS) == tune_exponential(ticks, kinds=KINDS)
    for bad, match in (
        ({"k_grid": (0.0, 1.0)}, "k_grid"),
        ({"thresholds": (1.5,)}, "thresholds"),
        ({"sweeps": 0}, "sweeps"),
        ({"form": "x"}, "form"),
    ):
        with pytest.raises(ValueError, match=match):
            tune_exponential(ticks, kinds=KINDS, **bad)
