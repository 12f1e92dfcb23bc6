"""Counterbalancing the order of the control modes over the participants of a
within-subjects study (thesis sections 7.5, 7.6.1.3; spec section 7).

Three schemes give participant ``i`` (from 0) an order of the modes: complete
counterbalancing (``"full_permutation"``, the thesis's six permutations), a Williams
design (``"williams"``, balanced Latin square) and simple randomisation (``"random"``).
:func:`balance` counts positions and adjacent pairs and words the experimenter's warnings.
Pure: no I/O, randomness only through the generator passed in.
"""

from __future__ import annotations

import hashlib
import itertools
import math
from collections import Counter
from collections.abc import Sequence
from typing import Any

import numpy as np

SCHEMES: tuple[str, ...] = ("full_permutation", "williams", "random")


def _check_modes(modes: Sequence[str]) -> tuple[str, ...]:
    modes = tuple(modes)
    if not modes:
        raise ValueError("modes: at least one mode is needed, got none")
    if not all(isinstance(m, str) and m for m in modes):
        raise ValueError(f"modes: must be non-empty strings, got {list(modes)!r}")
    duplicates = sorted(m for m, c in Counter(modes).items() if c > 1)
    if duplicates:
        raise ValueError(f"modes: must be distinct; {', '.join(duplicates)} appears twice")
    return modes


def _check_scheme(scheme: str) -> None:
    if scheme not in SCHEMES:
        raise ValueError(
            f"counterbalancing scheme: must be one of {', '.join(SCHEMES)}, got {scheme!r}"
        )


def williams_square(k: int) -> list[tuple[int, ...]]:
    """Rows of a Williams design (balanced Latin square, Williams 1949) for ``k`` conditions.

    The first row is ``0, 1, k-1, 2, k-2, ...`` and row ``r`` adds ``r`` to it modulo ``k``;
    for odd ``k`` the ``k`` mirrored rows follow. Over one cycle every condition appears in
    every position equally often and every ordered pair of different conditions is
    adjacent equally often (first-order carry-over balance).

    Parameters
    ----------
    k : int
        Number of conditions, >= 1.

    Returns
    -------
    list of tuple of int
        ``k`` rows for even ``k`` (and ``k == 1``), ``2k`` for odd ``k`` (the square and its
        mirror image); each row a permutation of ``0..k-1``.
    """
    if isinstance(k, bool) or not isinstance(k, int) or k < 1:
        raise ValueError(f"k: must be an integer >= 1, got {k!r}")
    first = [0]
    low, high = 1, k - 1
    for j in range(1, k):  # 0, 1, k-1, 2, k-2, ...
        if j % 2:
            first.append(low)
            low += 1
        else:
            first.append(high)
            high -= 1
    rows = [tuple((c + r) % k for c in first) for r in range(k)]
    if k % 2 and k > 1:
        rows += [row[::-1] for row in rows]
    return rows


def scheme_rows(modes: Sequence[str], scheme: str) -> list[tuple[str, ...]]:
    """The orders of one cycle of a deterministic scheme.

    ``full_permutation``: the ``k!`` permutations in :func:`itertools.permutations` order
    (the lexicographic order of the positions in ``modes``: for ``(a, b, c)`` the rows are
    abc, acb, bac, bca, cab, cba); ``n`` participants are completely counterbalanced when
    ``n`` is a multiple of ``k!``. ``williams``: the rows of :func:`williams_square`.
    ``random`` has no cycle (``ValueError``).
    """
    modes = _check_modes(modes)
    _check_scheme(scheme)
    if scheme == "full_permutation":
        return list(itertools.permutations(modes))
    if scheme == "williams":
        return [tuple(modes[j] for j in row) for row in williams_square(len(modes))]
    raise ValueError("counterbalancing scheme 'random' has no fixed rows; use assign()")


def cycle_length(k: int, scheme: str) -> int | None:
    """Participants per complete cycle of ``scheme`` with ``k`` modes (``None`` for random)."""
    _check_scheme(scheme)
    if scheme == "full_permutation":
        return math.factorial(k)
    if scheme == "williams":
        return k if k % 2 == 0 or k == 1 else 2 * k
    return None


def _permutation_index(perm: Sequence[int]) -> int:
    """Index of a permutation of ``0..k-1`` in :func:`itertools.permutations` order (its
    Lehmer code read as a factorial-base number)."""
    k, index = len(perm), 0
    for i, p in enumerate(perm):
        smaller_later = sum(1 for q in perm[i + 1 :] if q < p)
        index += smaller_later * math.factorial(k - 1 - i)
    return index


def assign_indexed(
    modes: Sequence[str],
    n: int,
    scheme: str,
    *,
    rng: np.random.Generator | None = None,
) -> list[tuple[int, tuple[str, ...]]]:
    """Like :func:`assign`, with each participant's row index (stored as ``order_index``).

    Participant ``i`` gets row ``i mod cycle`` of a deterministic scheme. With ``random``
    each participant draws a uniformly random permutation from ``rng``, independently (balance
    is not guaranteed; :func:`balance` reports what was reached), and the row index is that
    permutation's index in :func:`itertools.permutations` order of ``modes``.
    """
    modes = _check_modes(modes)
    _check_scheme(scheme)
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"participants: must be an integer >= 1, got {n!r}")
    if scheme == "random":
        if rng is None:
            raise ValueError("counterbalancing scheme 'random' needs a numpy Generator (rng)")
        out = []
        for _ in range(n):
            perm = [int(j) for j in rng.permutation(len(modes))]
            out.append((_permutation_index(perm), tuple(modes[j] for j in perm)))
        return out
    rows = scheme_rows(modes, scheme)
    return [(i % len(rows), rows[i % len(rows)]) for i in range(n)]


def site_seed(study_seed: int, site: str | None) -> int:
    """The seed of a site's random orders: the study seed in a study without sites (``site``
    None or ""), else a 63-bit hash of the study seed and the site's name, so that the sites
    draw independently (docs/decisions.md "Counterbalancing across sites")."""
    if not site:
        return study_seed
    digest = hashlib.sha256(f"{study_seed}:site:{site}".encode()).digest()
    return int.from_bytes(digest[:8], "little") >> 1


class SlotOrders:
    """The counterbalancing row and mode order of each slot of a study's order ledger
    (:mod:`study.data.ledger`): slot ``k`` (from 0) is participant ``k`` of
    :func:`assign_indexed`, i.e. row ``k mod cycle`` of a deterministic scheme and the
    ``k``-th draw of ``random`` from a generator seeded with ``seed`` (drawn in sequence,
    kept, so asking for slot ``k`` costs ``k`` draws once). A site of a multi-site study
    has its own ledger: the same rows of a deterministic scheme, its own random draws
    (:func:`site_seed`)."""

    def __init__(
        self, modes: Sequence[str], scheme: str, seed: int, site: str | None = None
    ) -> None:
        self.modes = _check_modes(modes)
        _check_scheme(scheme)
        self.scheme = scheme
        self.rows = scheme_rows(self.modes, scheme) if scheme != "random" else None
        self._rng = np.random.default_rng(site_seed(seed, site))
        self._drawn: list[tuple[int, tuple[str, ...]]] = []

    def __call__(self, slot: int) -> tuple[int, tuple[str, ...]]:
        """(row index, mode order) of ``slot`` (an integer >= 0)."""
        if self.rows is not None:
            return slot % len(self.rows), self.rows[slot % len(self.rows)]
        while len(self._drawn) <= slot:
            perm = [int(j) for j in self._rng.permutation(len(self.modes))]
            self._drawn.append((_permutation_index(perm), tuple(self.modes[j] for j in perm)))
        return self._drawn[slot]

    def row(self, slot: int) -> int:
        """The row index (``participant.order_index``) of ``slot``."""
        return self(slot)[0]


def assign(
    modes: Sequence[str],
    n: int,
    scheme: str,
    *,
    rng: np.random.Generator | None = None,
) -> list[tuple[str, ...]]:
    """The order of the modes for each of ``n`` participants.

    Parameters
    ----------
    modes : sequence of str
        The distinct mode names, in the protocol's order (it fixes the row order).
    n : int
        Number of participants, >= 1.
    scheme : {"full_permutation", "williams", "random"}
    rng : numpy.random.Generator, optional
        Required for ``"random"``; unused otherwise.

    Returns
    -------
    list of tuple of str
        ``n`` orders; participant ``i`` (from 0) gets element ``i``.

    Raises
    ------
    ValueError
        Fewer than one participant, no or duplicate modes, an unknown scheme, or ``random``
        without a generator.
    """
    return [order for _, order in assign_indexed(modes, n, scheme, rng=rng)]


def _counts_text(counts: dict[str, int]) -> str:
    return ", ".join(f"{m} {c}" for m, c in counts.items())


def _rows(first: int, last: int) -> str:
    """Rows (``order_index`` values, from 0) in words."""
    return f"row {first}" if first == last else f"rows {first}-{last}"


def _times(n: int) -> str:
    return {0: "never", 1: "once", 2: "twice"}.get(n, f"{n} times")


def _check_orders(orders: Sequence[Sequence[str]]) -> tuple[list[tuple[str, ...]], tuple[str, ...]]:
    """The orders as tuples and their modes; ``ValueError`` unless all permute the same modes."""
    orders = [tuple(o) for o in orders]
    if not orders:
        raise ValueError("orders: at least one participant's order is needed")
    modes = _check_modes(orders[0])
    for i, order in enumerate(orders):
        if sorted(order) != sorted(modes):
            raise ValueError(
                f"orders[{i}]: must be a permutation of {', '.join(modes)}, got {list(order)}"
            )
    return orders, modes


def _count(
    orders: list[tuple[str, ...]], modes: tuple[str, ...]
) -> tuple[dict[str, list[int]], dict[str, int]]:
    """Times each mode is in each position, and times ``b`` directly follows ``a`` ("a>b")."""
    positions = {m: [0] * len(modes) for m in modes}
    pairs = {f"{a}>{b}": 0 for a in modes for b in modes if a != b}
    for order in orders:
        for p, m in enumerate(order):
            positions[m][p] += 1
        for a, b in itertools.pairwise(order):
            pairs[f"{a}>{b}"] += 1
    return positions, pairs


def _warnings(
    modes: tuple[str, ...],
    n: int,
    positions: dict[str, list[int]],
    pairs: dict[str, int],
    scheme: str | None,
    cycle: int | None,
) -> list[str]:
    """The experimenter's warnings: unbalanced positions and carry-over, incomplete cycles."""
    k = len(modes)
    warnings: list[str] = []
    for p in range(k):
        counts = {m: positions[m][p] for m in modes}
        if len(set(counts.values())) > 1:
            warnings.append(f"position {p + 1} is unbalanced: {_counts_text(counts)}")
    if len(set(pairs.values())) > 1 and k > 1:
        low = min(pairs.values())
        rare = [pair for pair, c in pairs.items() if c == low]
        warnings.append(
            f"carry-over is unbalanced: adjacent pairs occur {low} to {max(pairs.values())} "
            f"times ({', '.join(rare)} least often)"
        )
    if cycle is not None and n % cycle != 0:
        whole, rest = divmod(n, cycle)
        suggestion = " or ".join(str(c * cycle) for c in (whole, whole + 1) if c > 0)
        warnings.append(
            f"{n} participants is not a multiple of the {scheme} cycle of {cycle}: "
            f"{_rows(0, rest - 1)} used {_times(whole + 1)}, {_rows(rest, cycle - 1)} "
            f"{_times(whole)}; "
            f"use {suggestion} participants for a balanced design"
        )
    return warnings


def balance(orders: Sequence[Sequence[str]], *, scheme: str | None = None) -> dict[str, Any]:
    """Position and carry-over balance of a list of mode orders, JSON-ready.

    Parameters
    ----------
    orders : sequence of sequence of str
        One order per participant, all permutations of the same modes.
    scheme : str, optional
        The scheme that made them; adds its cycle and whether ``n`` is a whole number of
        cycles, and decides ``balanced`` (see Returns).

    Returns
    -------
    dict
        ``modes`` (as in the first order), ``n``, ``position_counts`` (mode -> count per
        position), ``pair_counts`` ("a>b" -> times ``b`` directly follows ``a``, every ordered
        pair of different modes listed), ``order_counts`` ("a>b>c" -> participants, for the
        orders that occur), ``position_balanced``, ``carryover_balanced``,
        ``fully_counterbalanced`` (every permutation equally often), ``cycle`` (``None``
        without a deterministic scheme), ``complete_cycles`` (``n`` a multiple of it),
        ``balanced`` and ``warnings`` (list of str; rows are
        named by their ``order_index``, from 0). ``balanced`` is
        ``fully_counterbalanced`` for ``full_permutation``, position and carry-over balance
        for ``williams`` and for no scheme, and position balance for ``random``.

    Raises
    ------
    ValueError
        No orders, or orders that are not permutations of the same distinct modes.
    """
    orders, modes = _check_orders(orders)
    if scheme is not None:
        _check_scheme(scheme)
    k, n = len(modes), len(orders)
    positions, pairs = _count(orders, modes)
    permutation_counts = dict(Counter(">".join(order) for order in orders))

    position_balanced = all(len({positions[m][p] for m in modes}) == 1 for p in range(k))
    carryover_balanced = len(set(pairs.values())) <= 1
    fully = (
        len(permutation_counts) == math.factorial(k) and len(set(permutation_counts.values())) == 1
    )
    cycle = cycle_length(k, scheme) if scheme is not None else None
    complete = cycle is not None and n % cycle == 0
    warnings = _warnings(modes, n, positions, pairs, scheme, cycle)
    if scheme == "full_permutation":
        balanced = fully
    elif scheme == "random":
        balanced = position_balanced
    else:
        balanced = position_balanced and carryover_balanced
    return {
        "modes": list(modes),
        "n": n,
        "position_counts": positions,
        "pair_counts": pairs,
        "order_counts": permutation_counts,
        "position_balanced": position_balanced,
        "carryover_balanced": carryover_balanced,
        "fully_counterbalanced": fully,
        "cycle": cycle,
        "complete_cycles": complete,
        "balanced": balanced,
        "warnings": warnings,
    }
