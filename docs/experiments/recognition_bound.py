"""How far can per-tick recognition with the thesis's task feature go? (issues 16, 40)

Reproduces the figures of docs/results.md, "Issue 16: what the task feature can carry":

1. The trials of ``asa bench --only recognition`` (3 synthetic drivers x the shipped
   scenes with a dock, seed 1616, the shipped model), recording every tick's candidate
   components and task features (Eq. 6.1) from what the contextual mode was given (the
   observation's components and the driver's command) and what it answered (a view of
   the mode, :class:`Recorder`, passed to the trial as ``wrap_mode``: no private function
   of the mode is patched).
2. Offline, on exactly those ticks, one row per *recogniser* (a function from the recorded
   ticks to a decision per tick, :data:`Recogniser`): the mode's own decisions in the
   loop; the per-tick decision (Eq. 5.8); the same scores filtered over time (the
   recursive Bayes filter of Ch. 4, Eq. 4.4 with the transition 4.14, stay 0.95, the SOGP
   confidences 5.10 as the likelihood); and supervised upper bounds: a random forest
   trained on the *in-loop* candidate features and true labels of the other drivers
   (leave one driver out, same scenes, so an optimistic bound; one driver: its first and
   second half), on the thesis feature alone, with a point-vs-surface target bit, and
   with the component kind one-hot. :func:`recognisers` lists the rows; a further
   recogniser is one more entry (``measure(rows, {**recognisers(), "mine": mine})``).

Run from the repository root (about 6 minutes on 2 cores; ``--generated 10 --drivers
2``: the generated floor plans of seeds 0-9 instead, 2 drivers each, about 15 minutes):

    python docs/experiments/recognition_bound.py [--out DIR] [--generated N] [--drivers D]
"""

from __future__ import annotations

import argparse
import functools
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.special import ndtr
from sklearn.ensemble import RandomForestClassifier

from autonomy.features import encode, task_features
from autonomy.model import load_model
from autonomy.task_types import contextual_task, primitive_motions
from autonomy.types import as_candidates
from sim.scenario import load_scenario
from study.bench.recognition import _SEED, drivable_scenes, scene_recognition, write_generated
from study.data.storage import open_database

KINDS = ("doorway", "gap", "dock", "object", "wall")

# the recorded ticks -> per tick (true task, true target, recognised task, target)
Recogniser = Callable[[list[dict]], list[tuple[str, str, str, str]]]


class Recorder:
    """The contextual mode as the trial sees it, recording per step the candidates it was
    offered (the ``candidates`` components nearest by target point, stable order, as the
    mode takes them; none when the command is below ``min_input`` or there is none), their
    kinds and task features (Eq. 6.1) for the normalised command, and the mode's answer.
    """

    def __init__(self, mode: Any, log: list[tuple]) -> None:
        self.mode, self.log = mode, log
        settings = mode.settings_dict()
        self.n = int(settings.get("candidates", 10))
        self.min_input = float(settings.get("min_input", 0.05))
        self.name = mode.name
        self.limit = np.ones(3)

    def reset(self, robot: Any) -> None:
        self.limit = np.array([robot.max_speed, robot.max_speed, robot.max_yaw_rate])
        self.mode.reset(robot)

    def label_tasks(self) -> dict[str, str] | None:
        return self.mode.label_tasks()

    def settings_dict(self) -> dict[str, Any]:
        return self.mode.settings_dict()

    def step(self, obs: Any, u: np.ndarray) -> Any:
        out = self.mode.step(obs, u)
        u_norm = np.asarray(u, dtype=float) / self.limit
        ids = kinds = q = None
        if len(obs.components) and np.hypot(u_norm[0], u_norm[1]) >= self.min_input:
            ids, kinds, q = _candidates(as_candidates(obs.components), u_norm, self.n)
        self.log.append((ids, kinds, q, out.label, out.target))
        return out


def _candidates(components: Any, u_norm: np.ndarray, n: int) -> tuple[list, list, np.ndarray]:
    """The ``n`` components nearest the robot by target point (stable order): their ids,
    kinds and task features (m, 6) for the normalised command ``u_norm`` (3,)."""
    targets = np.asarray(components.target_points(), dtype=float).reshape(-1, 2)
    d2 = targets[:, 0] * targets[:, 0] + targets[:, 1] * targets[:, 1]
    order = np.argsort(d2, kind="stable")[:n]
    ids = [str(components[int(k)].id) for k in order]
    kinds = [str(components[int(k)].kind) for k in order]
    return ids, kinds, task_features(targets[order], u_norm)


def record(
    folder: Path, drivers: int, scenes: list[str], mode_settings: dict | None = None
) -> list[dict]:
    """Every tick of the bench's trials (the contextual mode with ``mode_settings``):
    candidate ids, kinds, features, the mode's label and target, the true labels."""
    rows: list[dict] = []
    outside = 0  # ticks whose recognised target is none of the recorded candidates
    for scene in scenes:
        log: list[tuple] = []
        wrap = functools.partial(Recorder, log=log)
        scene_recognition(folder, scene, drivers, _SEED, mode_settings, wrap_mode=wrap)
        truth = _truth(folder, load_scenario(scene).name, drivers)
        if len(truth) != len(log):
            raise RuntimeError(f"{scene}: {len(truth)} samples but {len(log)} mode steps")
        for (ids, kinds, q, label, target), t in zip(log, truth, strict=True):
            if label != t["label"] or target != t["target"]:
                raise RuntimeError(f"{scene}: the recorded step is not the stored sample")
            outside += bool(target) and (ids is None or target not in ids)
            rows.append({"scene": scene, **t, "ids": ids, "kinds": kinds, "q": q})
    if outside:
        print(f"note: {outside} ticks recognised a target outside the recorded candidates")
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


def _folds(rows: list[dict], ticks: np.ndarray) -> np.ndarray:
    """The fold of every tick index in ``ticks``: its driver (scene and driver number), or
    with a single driver its half of the recorded ticks."""
    keys = [(rows[n]["scene"], rows[n]["driver"]) for n in ticks]
    if len(set(keys)) > 1:
        index = {k: i for i, k in enumerate(dict.fromkeys(keys))}
        return np.array([index[k] for k in keys])
    return (np.asarray(ticks) >= len(rows) // 2).astype(int)


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
    driver = _folds(rows, keys[:, 0])
    chosen: dict[int, tuple[str, str]] = {}
    for d in np.unique(driver):
        fit = RandomForestClassifier(200, min_samples_leaf=5, random_state=0, n_jobs=2)
        fit.fit(X[driver != d], y[driver != d])
        P = fit.predict_proba(X[driver == d])
        if "none" in fit.classes_:
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


def in_loop_decisions(rows: list[dict]) -> list[tuple]:
    """The mode's own decisions in the loop (its label is the task type)."""
    return [(r["true_task"], r["true_target"], r["label"], r["target"]) for r in rows]


def recognisers() -> dict[str, Recogniser]:
    """The table's rows: name -> recogniser."""
    return {
        "in the loop (the mode's own output)": in_loop_decisions,
        "shipped recogniser, Eq. 5.8 per tick": functools.partial(sogp_decisions, stay=None),
        "Ch. 4 filter over the SOGP confidences": functools.partial(sogp_decisions, stay=0.95),
        "forest on in-loop data (thesis feature)": functools.partial(forest_decisions, extra=""),
        "forest on in-loop data (+ point/surface bit)": functools.partial(
            forest_decisions, extra="point"
        ),
        "forest on in-loop data (+ kind one-hot)": functools.partial(
            forest_decisions, extra="kind"
        ),
    }


def measure(rows: list[dict], table: dict[str, Recogniser] | None = None) -> dict[str, dict]:
    """Every recogniser of ``table`` (default :func:`recognisers`) scored on the recorded
    ticks ``rows``: name -> {"task", "task_target", "per_task"} (shares of the labelled
    ticks)."""
    table = recognisers() if table is None else table
    return {name: _score(decide(rows)) for name, decide in table.items()}


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
    for name, score in measure(rows).items():
        print(f"{name}:", score)


if __name__ == "__main__":
    main()
