"""Counterbalancing: full permutation, Williams squares, seeded random, and the balance check."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from study.engine.counterbalance import (
    SCHEMES,
    assign,
    assign_indexed,
    balance,
    cycle_length,
    scheme_rows,
    williams_square,
)

MODES3 = ("manual", "reactive_bn", "contextual_task")


def names(k: int) -> tuple[str, ...]:
    return tuple(f"mode{i}" for i in range(k))


@settings(max_examples=20, deadline=None)
@given(k=st.integers(2, 4), reps=st.integers(1, 3))
def test_full_permutation_gives_each_order_equally_often(k, reps):
    modes = names(k)
    n = math.factorial(k) * reps
    orders = assign(modes, n, "full_permutation")
    perms = list(itertools.permutations(modes))
    # participant i gets permutation i mod k!, in itertools order
    assert orders == [perms[i % len(perms)] for i in range(n)]
    counts = {p: orders.count(p) for p in perms}
    assert set(counts.values()) == {reps}
    check = balance(orders, scheme="full_permutation")
    assert check["balanced"] and check["fully_counterbalanced"] and check["complete_cycles"]
    assert check["warnings"] == []


@pytest.mark.parametrize("k", [2, 3, 4, 5, 6])
def test_williams_square_is_balanced_for_position_and_carry_over(k):
    rows = williams_square(k)
    assert len(rows) == (k if k % 2 == 0 else 2 * k)
    assert all(sorted(row) == list(range(k)) for row in rows)
    # each condition once per position per square: equal column counts
    for p in range(k):
        column = [row[p] for row in rows]
        assert len({column.count(c) for c in range(k)}) == 1
    # each ordered pair of different conditions adjacent equally often
    pairs = [pair for row in rows for pair in itertools.pairwise(row)]
    counts = {(a, b): pairs.count((a, b)) for a in range(k) for b in range(k) if a != b}
    assert len(set(counts.values())) == 1
    assert sum(counts.values()) == len(rows) * (k - 1)


@settings(max_examples=25, deadline=None)
@given(k=st.integers(2, 6), cycles=st.integers(1, 3))
def test_williams_assignment_over_whole_cycles_is_balanced(k, cycles):
    modes = names(k)
    cycle = cycle_length(k, "williams")
    orders = assign(modes, cycle * cycles, "williams")
    check = balance(orders, scheme="williams")
    assert check["position_balanced"] and check["carryover_balanced"] and check["balanced"]
    assert check["complete_cycles"] and check["warnings"] == []
    assert all(set(c) == {cycles * cycle // k} for c in check["position_counts"].values())


def test_williams_rows_follow_the_scheme_order():
    rows = scheme_rows(MODES3, "williams")
    orders = assign(MODES3, 13, "williams")
    assert orders == [rows[i % 6] for i in range(13)]


def test_random_is_reproducible_per_seed_and_valid(seed):
    a = assign_indexed(MODES3, 30, "random", rng=np.random.default_rng(seed))
    b = assign_indexed(MODES3, 30, "random", rng=np.random.default_rng(seed))
    c = assign_indexed(MODES3, 30, "random", rng=np.random.default_rng(seed + 1))
    assert a == b
    assert a != c  # equal with probability 6**-30
    perms = list(itertools.permutations(MODES3))
    for index, order in a:
        assert perms[index] == order


def test_random_draws_every_order_about_equally(rng):
    orders = assign(MODES3, 6000, "random", rng=rng)
    counts = np.array([orders.count(p) for p in itertools.permutations(MODES3)])
    # binomial sd is about 29; six sd either side of 1000
    assert np.all(np.abs(counts - 1000) < 175)


def test_eighteen_participants_balance_and_ten_do_not():
    full = balance(assign(MODES3, 18, "full_permutation"), scheme="full_permutation")
    assert full["balanced"] and full["warnings"] == []
    assert all(counts == [6, 6, 6] for counts in full["position_counts"].values())
    assert set(full["pair_counts"].values()) == {6}

    ten = assign(MODES3, 10, "full_permutation")
    check = balance(ten, scheme="full_permutation")
    assert not check["balanced"] and not check["complete_cycles"]
    expected_bad = [
        p + 1 for p in range(3) if len({sum(o[p] == m for o in ten) for m in MODES3}) > 1
    ]
    assert expected_bad  # 10 is not a multiple of 6
    for p in range(1, 4):
        said = any(w.startswith(f"position {p} is unbalanced") for w in check["warnings"])
        assert said == (p in expected_bad)
    assert any("not a multiple" in w and "6" in w for w in check["warnings"])


@settings(max_examples=30, deadline=None)
@given(k=st.integers(2, 5), n=st.integers(1, 40), scheme=st.sampled_from(SCHEMES))
def test_balance_counts_add_up(k, n, scheme):
    orders = assign(names(k), n, scheme, rng=np.random.default_rng(n))
    check = balance(orders, scheme=scheme)
    for p in range(k):
        assert sum(check["position_counts"][m][p] for m in names(k)) == n
    assert sum(check["pair_counts"].values()) == n * (k - 1)
    assert sum(check["order_counts"].values()) == n
    assert len(check["pair_counts"]) == k * (k - 1)
    if check["position_balanced"]:
        assert n % k == 0
    assert check["balanced"] == (check["warnings"] == []) or scheme == "random"


@pytest.mark.parametrize(
    ("modes", "n", "scheme", "needle"),
    [
        (MODES3, 0, "full_permutation", "participants"),
        (MODES3, -3, "williams", "participants"),
        (("manual", "manual", "reactive_bn"), 6, "full_permutation", "appears twice"),
        ((), 6, "full_permutation", "at least one mode"),
        (MODES3, 6, "latin_square", "full_permutation, williams, random"),
        (MODES3, 6, "random", "Generator"),  # no rng
    ],
)
def test_impossible_requests_are_refused(modes, n, scheme, needle):
    with pytest.raises(ValueError, match=needle):
        assign(modes, n, scheme)


def test_balance_refuses_inconsistent_orders():
    with pytest.raises(ValueError, match=r"orders\[1\]"):
        balance([("a", "b"), ("a", "c")])
    with pytest.raises(ValueError, match="at least one"):
        balance([])
