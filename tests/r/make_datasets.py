"""Write the seeded test datasets of tests/r/ (long CSVs) and their manifest.

Run from the repository root: ``python tests/r/make_datasets.py``; then ``Rscript
tests/r/oracle.R`` writes the golden JSON files from them (tests/r/golden/). Each dataset is a
case the R oracle must agree on (issue 21): a sphericity violation, a count with many zeros, a
Likert item, a participant missing one level, a 4-level design; plus Field's Bushtucker data
(typed in, no order column).
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pandas as pd

HERE = Path(__file__).parent
SEED = 20260521


def _orders(levels: list[str], n: int, rng: np.random.Generator) -> list[list[str]]:
    """Counterbalanced orders: every permutation in turn (shuffled), n of them."""
    perms = [list(p) for p in itertools.permutations(levels)]
    rng.shuffle(perms)
    return [perms[i % len(perms)] for i in range(n)]


def _long(values: dict[tuple[str, str], float], orders: dict[str, list[str]]) -> pd.DataFrame:
    rows = []
    for subject, order in orders.items():
        for position, level in enumerate(order, start=1):
            if (subject, level) in values:
                rows.append((subject, level, position, values[subject, level]))
    return pd.DataFrame(rows, columns=["participant", "mode", "position", "y"])


def sphericity(rng: np.random.Generator) -> pd.DataFrame:
    """3 levels, 12 participants; level c's noise 6x the others' and tied to the subject."""
    levels, n = ["a", "b", "c"], 12
    orders = dict(zip([f"S{i:02d}" for i in range(n)], _orders(levels, n, rng), strict=True))
    values = {}
    for subject in orders:
        person = rng.normal(0, 4)
        shock = rng.normal(0, 6)
        for j, level in enumerate(levels):
            noise = shock if level == "c" else rng.normal(0, 1)
            values[subject, level] = round(50 + person + 4.0 * j + noise, 3)
    return _long(values, orders)


def zeros(rng: np.random.Generator) -> pd.DataFrame:
    """Collision counts: mostly zero in two modes, more in the third; 12 participants."""
    levels, n = ["manual", "reactive", "contextual"], 12
    orders = dict(zip([f"P{i:02d}" for i in range(n)], _orders(levels, n, rng), strict=True))
    rates = {"manual": 2.0, "reactive": 0.3, "contextual": 0.2}
    values = {(s, lv): float(rng.poisson(rates[lv])) for s in orders for lv in levels}
    return _long(values, orders)


def likert(rng: np.random.Generator) -> pd.DataFrame:
    """A single 7-point rating item, 15 participants, 3 modes."""
    levels, n = ["manual", "reactive", "contextual"], 15
    orders = dict(zip([f"P{i:02d}" for i in range(n)], _orders(levels, n, rng), strict=True))
    shift = {"manual": 0.0, "reactive": 0.8, "contextual": 1.4}
    values = {}
    for subject in orders:
        person = rng.normal(0, 0.8)
        for level in levels:
            latent = 3.5 + person + shift[level] + rng.normal(0, 0.9)
            values[subject, level] = float(np.clip(np.round(latent), 1, 7))
    return _long(values, orders)


def missing(rng: np.random.Generator) -> pd.DataFrame:
    """Completion times, 10 participants, 3 modes; P03 lacks one mode (listwise vs mixed)."""
    levels, n = ["manual", "reactive", "contextual"], 10
    orders = dict(zip([f"P{i:02d}" for i in range(n)], _orders(levels, n, rng), strict=True))
    effect = {"manual": 0.0, "reactive": -8.0, "contextual": -12.0}
    values = {}
    for subject, order in orders.items():
        person = rng.normal(0, 10)
        for position, level in enumerate(order):
            values[subject, level] = round(
                120 + person + effect[level] - 3.0 * position + rng.normal(0, 5), 2
            )
    del values["P03", orders["P03"][1]]
    return _long(values, orders)


def four_levels(rng: np.random.Generator) -> pd.DataFrame:
    """4 levels, 12 participants in a cyclic Latin square, a moderate effect."""
    levels, n = ["L1", "L2", "L3", "L4"], 12
    square = [levels[i:] + levels[:i] for i in range(4)]
    orders = {f"P{i:02d}": square[i % 4] for i in range(n)}
    values = {}
    for subject in orders:
        person = rng.normal(0, 3)
        for j, level in enumerate(levels):
            values[subject, level] = round(20 + person + 2.5 * (j == 3) + rng.normal(0, 1.5), 3)
    return _long(values, orders)


DATASETS = {
    "sphericity": (sphericity, "y"),
    "zeros": (zeros, "collisions"),
    "likert": (likert, "rating"),
    "missing": (missing, "completion_time_s"),
    "four_levels": (four_levels, "y"),
}


def main() -> None:
    rng = np.random.default_rng(SEED)
    manifest = [
        {
            "name": "bushtucker",
            "csv": "bushtucker.csv",
            "dv": "retch_s",
            "within": "animal",
            "subject": "celebrity",
            "order": None,
        }
    ]
    for name, (make, dv) in DATASETS.items():
        frame = make(rng).rename(columns={"y": dv})
        frame.to_csv(HERE / f"{name}.csv", index=False)
        entry = {"name": name, "csv": f"{name}.csv", "dv": dv, "within": "mode"}
        manifest.append({**entry, "subject": "participant", "order": "position"})
    (HERE / "datasets.json").write_text(json.dumps(manifest, indent=1) + "\n")


if __name__ == "__main__":
    main()
