"""How far can per-tick recognition with the thesis's task feature go? (issue 16)

Reproduces the figures of docs/results.md, "Issue 16: what the task feature can carry":

1. The trials of ``asa bench --only recognition`` (3 synthetic drivers x the shipped
   scenes with a dock, seed 1616, the shipped model), recording every tick's candidate
   components and task features (Eq. 6.1) as the contextual mode computed them.
2. Offline, on exactly those ticks: the mode's own per-tick decision (Eq. 5.8), the
   same scores filtered over time (the recursive Bayes filter of Ch. 4, Eq. 4.4 with
   the transition 4.14, stay 0.95, the SOGP confidences 5.10 as the likelihood), and
   supervised upper bounds: a random forest trained on the *in-loop* candidate features
   and true labels of the other drivers (leave one driver out, same scenes, so an
   optimistic bound), on the thesis feature alone, with a point-vs-surface target bit,
   and with the component kind one-hot.

Run from the repository root (about 6 minutes on 2 cores; ``--generated 10 --drivers
2``: the generated floor plans of seeds 0-9 instead, 2 drivers each, about 15 minutes):

    python docs/experiments/recognition_bound.py [--out DIR] [--generated N] [--drivers D]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.special import ndtr
from sklearn.ensemble import RandomForestClassifier

import autonomy.contextual as ctx
from autonomy.features import encode
from autonomy.model import load_model
from autonomy.task_types import contextual_task, primitive_motions
from sim.scenario import load_scenario
from study.bench.recognition import _SEED, drivable_scenes, scene_recognition, write_generated
from study.data.storage import open_database

KINDS = ("doorway", "gap", "dock", "object", "wall")


def record(folder: Path, drivers: int, scenes: list[str]) -> list[dict]:
    """Every tick of the bench's trials: candidate ids, kinds, features, true labels."""
    log: list[tuple] = []
    seen: dict = {}
    near, step = ctx._nearest_candidates, ctx.ContextualTaskMode.step

    def nearest(components, n):
        targets, order = near(components, n)
        seen["ids"] = [str(components[int(k)].id) for k in order]
        seen["kinds"] = [str(components[int(k)].kind) for k in order]
        seen["q"] = ctx.task_features(targets[order], seen["u"])
        return targets, order

    def stepping(self, obs, u):
        seen.clear()
        limit = np.array([self.robot_.max_speed] * 2 + [self.robot_.max_yaw_rate])
        seen["u"] = np.asarray(u, dtype=float) / limit
        out = step(self, obs, u)
        log.append((seen.get("ids"), seen.get("kinds"), seen.get("q"), out.label, out.target))
        return out

    ctx._nearest_candidates, ctx.ContextualTaskMode.step = nearest, stepping
    rows: list[dict] = []
    try:
        for scene in scenes:
            log.clear()
            scene_recognition(folder, scene, drivers, _SEED)
            truth = _truth(folder, load_scenario(scene).name, drivers)
            if len(truth) != len(log):
                raise RuntimeError(f"{scene}: {len(truth)} samples but {len(log)} mode steps")
            for (ids, kinds, q, label, target), t in zip(log, truth, strict=True):
                if label != t["label"] or target != t["target"]:
                    raise RuntimeError(f"{scene}: the recorded step is not the stored sample")
                rows.append({"scene": scene, **t, "ids": ids, "kinds": kinds, "q": q})
    finally:
        ctx._nearest_candidates, ctx.ContextualTaskMode.step = near, step
    return rows


def _truth(folder: Path, scene: str, drivers: int) -> list[dict]:
    out = []
    for k in range(drivers):
        engine = open_database(folder / f"{scene}_{k}.db")
        s = pd.read_sql(
            "select label, target, true_task, true_target from sample order by tick", engine
        )
        engine.dispose()
        s["driver"] = k
        out += s.to_dict("records")
    return out


def _score(decisions: list[tuple[str, str, str, str]]) -> dict:
    df = pd.DataFrame(decisions, columns=["tt", "tg", "task", "target"])
    df = df[df.tt != ""]
    task = df.task == df.tt
    both = task & (df.target == df.tg)
    return {
        "task": round(float(task.mean()), 3),
        "task_target": round(float(both.mean()), 3),
        "per_task": df.assign(b=both).groupby("tt").b.mean().round(2).to_dict(),
    }


def sogp_decisions(rows: list[dict], stay: float | None) -> list[tuple]:
    """Eq. 5.8 per tick (``stay`` None) or the Ch. 4 filter over (component, primitive)."""
    model = load_model()
    clf = model.classifier
    motions = primitive_motions(model.metadata.get("clusters", []))
    classes = [int(c) for c in clf.classes_]
    out, belief, driver = [], {}, None
    for r in rows:
        if (r["scene"], r["driver"]) != driver:
            belief, driver = {}, (r["scene"], r["driver"])
        if r["ids"] is None:
            out.append((r["true_task"], r["true_target"], "", ""))
            continue
        mean, var = clf.decision(model.scaler.transform(encode(r["q"])))
        if stay is None:
            i, j = np.unravel_index(np.argmax(mean), mean.shape)  # Eq. (5.8)
        else:
            i, j = _filtered(belief, r["ids"], ndtr(mean / np.sqrt(var)), stay)
        task = contextual_task(r["kinds"][i], motions.get(classes[j], ""))
        out.append((r["true_task"], r["true_target"], task, r["ids"][i]))
    return out


def _filtered(belief: dict, ids: list[str], lik: np.ndarray, stay: float) -> tuple[int, int]:
    m, c = lik.shape
    states = [(ids[i], j) for i in range(m) for j in range(c)]
    n = len(states)
    old = np.array([belief.get(x, np.nan) for x in states])
    new = np.isnan(old)
    if np.nansum(old) <= 0:
        b = np.full(n, 1.0 / n)
    else:  # survivors keep their share, new states enter at 1/n
        b = np.where(new, 0.0, old)
        b = b / b.sum() * (1.0 - new.sum() / n)
        b[new] = 1.0 / n
    b = stay * b + (1.0 - stay) * (1.0 - b) / (n - 1)  # Eq. (4.14)
    b = b * lik.ravel() + 1e-300  # Eq. (4.4)
    b /= b.sum()
    belief.clear()
    belief.update(zip(states, b, strict=True))
    k = int(np.argmax(b))
    return k // c, k % c


def forest_decisions(rows: list[dict], extra: str) -> list[tuple]:
    """Leave-one-driver-out random forest over candidates: class = the true task for the
    true target's row, "none" for every other candidate; the tick's decision is the
    candidate and task with the largest non-"none" probability."""
    feats, labels, keys = [], [], []
    for n, r in enumerate(rows):
        if r["ids"] is None or r["true_task"] == "":
            continue
        z = encode(r["q"])
        for i, (cid, kind) in enumerate(zip(r["ids"], r["kinds"], strict=True)):
            if extra == "kind":
                z_i = np.concatenate((z[i], [kind == k for k in KINDS]))
            elif extra == "point":
                z_i = np.append(z[i], kind in ("doorway", "gap", "dock"))
            else:
                z_i = z[i]
            feats.append(z_i)
            labels.append(r["true_task"] if cid == r["true_target"] else "none")
            keys.append((n, i))
    X, y, keys = np.array(feats), np.array(labels), np.array(keys)
    driver = np.array([rows[n]["driver"] for n, _ in keys])
    chosen: dict[int, tuple[str, str]] = {}
    for d in np.unique(driver):
        fit = RandomForestClassifier(200, min_samples_leaf=5, random_state=0, n_jobs=2)
        fit.fit(X[driver != d], y[driver != d])
        P = fit.predict_proba(X[driver == d])
        P[:, list(fit.classes_).index("none")] = -1.0
        best: dict[int, tuple[float, str, str]] = {}
        for (n, i), p in zip(keys[driver == d], P, strict=True):
            j = int(np.argmax(p))
            if n not in best or p[j] > best[n][0]:
                best[n] = (float(p[j]), str(fit.classes_[j]), rows[n]["ids"][i])
        chosen.update({n: (task, target) for n, (_, task, target) in best.items()})
    return [
        (r["true_task"], r["true_target"], *chosen.get(n, ("", ""))) for n, r in enumerate(rows)
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None, help="keep the trial databases here")
    parser.add_argument("--drivers", type=int, default=3)
    parser.add_argument(
        "--generated", type=int, default=0, help="the generated floor plans 0..N-1 instead"
    )
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.out or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        scenes = drivable_scenes()
        if args.generated:
            scenes = write_generated(folder, tuple(range(args.generated)))
        rows = record(folder, args.drivers, scenes)
    print("labelled ticks:", sum(r["true_task"] != "" for r in rows))
    print("shipped recogniser, Eq. 5.8 per tick:", _score(sogp_decisions(rows, None)))
    print("Ch. 4 filter over the SOGP confidences:", _score(sogp_decisions(rows, 0.95)))
    for extra, what in (
        ("", "thesis feature"),
        ("point", "+ point/surface bit"),
        ("kind", "+ kind one-hot"),
    ):
        print(f"forest on in-loop data ({what}):", _score(forest_decisions(rows, extra)))


if __name__ == "__main__":
    main()
