"""The kind-and-time recogniser (:mod:`autonomy.kind_time`, issue 40) in the offline
evaluation (thesis Sec. 7.2.2, 7.3.2, 7.4.1, 7.4.3): its intent prior fitted on a fold's
training ticks as ``asa train`` fits the shipped model's (the evaluation's SOGP classes,
task types, standing for the primitives), replayed tick by tick along held-out runs on
the SOGP's posterior means, and what the evaluation reads off it: the decisive task and
target (trajectory rates), the most believed candidate (ACR, MICAD) and the belief's
normalised entropy (Eq. 7.7) with its belief in no task (introspection). Choices:
docs/decisions.md, "autonomy/evaluation/kind_time.py".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from autonomy.evaluation.classifiers import FittedClassifier, fit_method
from autonomy.evaluation.correspondence import correspondence_rates, intra_cluster_dissimilarity
from autonomy.evaluation.folds import EvaluationData, hard_negatives, way_points_of
from autonomy.evaluation.metrics import trajectory_rates
from autonomy.features import FeatureScaler
from autonomy.intent_prior import IntentPrior, demonstrated_prior
from autonomy.kind_time import NULL, KindTimeRecogniser
from autonomy.sogp_classifier import SOGPClassifier, normalised_entropy
from autonomy.task_types import contextual_task
from autonomy.training import DemoCandidates

Decision = tuple[str, str] | None  # (task type, component id), None: no decision


@dataclass(frozen=True, slots=True)
class Replay:
    """The recogniser along ``t`` ticks of one run."""

    row: np.ndarray  # (t,) int candidate row (of the data) with the most belief, -1 none
    col: np.ndarray  # (t,) int its best class column (of the SOGP), -1 on an idle tick
    decisive: np.ndarray  # (t,) bool: blend weight > 0, the mode would assist
    entropy: np.ndarray  # (t,) normalised entropy (7.7) of the belief in [0, 1]
    no_task: np.ndarray  # (t,) the belief in the no-task hypothesis


@dataclass(frozen=True, slots=True)
class KindTimeFold:
    """What the kind-and-time recogniser contributes to a held-out fold."""

    cr: dict[str, float]  # held-out run -> correspondence rate
    icad: np.ndarray  # (t,) ICAD of the scored ticks with a class [standardised units]
    rates: list[dict[str, float]]  # per held-out run: success, error, null
    entropy: np.ndarray  # (t,) belief entropy (7.7) at the scored test ticks
    decisive: np.ndarray  # (t,) bool at the scored test ticks
    no_task: np.ndarray  # (t,) belief in no task at the scored test ticks


def fit_prior(data: EvaluationData, rows: np.ndarray, classes: np.ndarray) -> IntentPrior:
    """The intent prior of training ticks ``rows`` (:func:`~autonomy.intent_prior.
    demonstrated_prior`, as ``autonomy.training.train`` fits it), each tick labelled with
    its task type index (the SOGP's class), aligned with ``classes`` (J,)."""
    rows = np.asarray(rows)
    a, b = data.off[rows], data.off[rows + 1]
    cand = np.concatenate([np.arange(x, y) for x, y in zip(a, b, strict=True)] or [[]])
    cand = cand.astype(int)
    candidates = DemoCandidates(
        points=data.pts[cand],
        offsets=np.r_[0, np.cumsum(b - a)],
        ids=data.ids[cand],
        target=data.target[rows],
        kinds=data.ckinds[cand],
    )
    prior = demonstrated_prior(data.q[rows], data.y[rows], candidates, data.executing[rows])
    return IntentPrior.from_metadata({"intent_prior": prior}, classes)


def _belief_entropy(belief: dict[str, float]) -> float:
    """Normalised entropy (7.7) of a belief; 1 (uniform) before any belief."""
    if not belief:
        return 1.0
    return float(normalised_entropy(np.fromiter(belief.values(), dtype=float)))


def _no_task(belief: dict[str, float], n: int) -> float:
    """The belief in no task; before any belief the uniform share of ``n`` candidates
    and no task."""
    return belief.get(NULL, 0.0) if belief else 1.0 / (n + 1)


def _most_believed(belief: dict[str, float], ids: np.ndarray) -> int:
    """Index into ``ids`` of the candidate with the most belief (the first of equals),
    -1 when none has any."""
    values = [belief.get(str(c), 0.0) for c in ids]
    best = max(range(len(values)), key=values.__getitem__, default=-1)
    return best if best >= 0 and values[best] > 0.0 else -1


def replay_run(
    rec: KindTimeRecogniser, means: np.ndarray, data: EvaluationData, ticks: np.ndarray
) -> Replay:
    """The recogniser along one run's ``ticks`` (consecutive rows), reset at its start.

    ``means`` (m_r, J) are the SOGP posterior means (Eq. 5.6) of the run's candidate rows
    ``data.off[ticks[0]]:data.off[ticks[-1] + 1]``, in order.
    """
    rec.reset()
    base = int(data.off[ticks[0]])
    t = len(ticks)
    row, col = np.full(t, -1), np.full(t, -1)
    decisive, entropy, no_task = np.zeros(t, dtype=bool), np.ones(t), np.zeros(t)
    min_input = data.settings.min_input
    for n, i in enumerate(ticks):
        a, b = int(data.off[i]), int(data.off[i + 1])
        u = data.u_norm[i]
        m = means[a - base : b - base]
        if b == a or math.hypot(u[0], u[1]) < min_input:
            rec.idle()  # the mode's tick without input
            r = _most_believed(rec.belief_, data.ids[a:b])
            row[n] = a + r if r >= 0 else -1
        elif np.isfinite(m).any():  # the mode recognises nothing without a finite mean
            found = rec(m, data.ids[a:b].tolist(), data.ckinds[a:b].tolist(),
                        data.pts[a:b], data.normals[a:b], u)  # fmt: skip
            row[n], col[n] = a + found.candidate, found.primitive
            decisive[n] = found.beta > 0.0
        entropy[n] = _belief_entropy(rec.belief_)
        no_task[n] = _no_task(rec.belief_, b - a)
    return Replay(row, col, decisive, entropy, no_task)


def _decisions(data: EvaluationData, replay: Replay, classes: np.ndarray) -> list[Decision]:
    """Per tick: (task type of the candidate's kind and class, component id) where the
    recogniser is decisive, else None."""
    out: list[Decision] = []
    for r, c, d in zip(replay.row, replay.col, replay.decisive, strict=True):
        if d and r >= 0 and c >= 0:
            motion = data.labels[int(classes[c])]
            out.append((contextual_task(str(data.ckinds[r]), motion), str(data.ids[r])))
        else:
            out.append(None)
    return out


def runs_of(data: EvaluationData, ticks: np.ndarray) -> list[np.ndarray]:
    """``ticks`` (sorted) split by run."""
    ticks = np.asarray(ticks)
    cut = np.flatnonzero(np.diff(data.run[ticks]) != 0) + 1
    return np.split(ticks, cut) if len(ticks) else []


def run_means(
    model: SOGPClassifier, Z_cand: np.ndarray, data: EvaluationData, ticks: np.ndarray
) -> np.ndarray:
    """SOGP posterior means (Eq. 5.6) of the candidates of one run's ``ticks``."""
    return np.asarray(model.scores(Z_cand[data.off[ticks[0]] : data.off[ticks[-1] + 1]]))


def kind_time_fold(
    data: EvaluationData,
    k: int,
    sogp: FittedClassifier,
    Z_cand: np.ndarray,
    Z_train: np.ndarray,
    y_train: np.ndarray,
) -> KindTimeFold:
    """The kind-and-time recogniser on held-out fold ``k``: the prior fitted on every
    tick of the training fold's runs, the fold's SOGP (``sogp``, a
    :class:`~autonomy.evaluation.classifiers.FittedClassifier`) for the means of
    ``Z_cand`` (m, 7, standardised on the training fold); replayed along every
    held-out run; CR and ICAD (to the training way points ``Z_train``, ``y_train``) on the
    scored test ticks (every ``test_stride``-th), the trajectory rates on every tick."""
    prior = fit_prior(data, np.flatnonzero(data.fold != k), sogp.classes)
    rec = KindTimeRecogniser(prior, data.settings.kind_time)
    held_out = np.flatnonzero(data.fold == k)
    hits, runs, icad, entropy, decisive, no_task = [], [], [], [], [], []
    rates: list[dict[str, float]] = []
    for ticks in runs_of(data, held_out):
        replay = replay_run(rec, run_means(sogp.model, Z_cand, data, ticks), data, ticks)
        truth = [(data.task[i], data.target[i]) for i in ticks]
        rates.append(trajectory_rates(_decisions(data, replay, sogp.classes), truth))
        scored = way_points_of(data.run[ticks], data.settings.test_stride)
        row, col = replay.row[scored], replay.col[scored]
        hits.append((row >= 0) & (data.ids[np.maximum(row, 0)] == data.target[ticks[scored]]))
        runs.append(data.run[ticks[scored]])
        found = (row >= 0) & (col >= 0)
        icad.append(
            intra_cluster_dissimilarity(
                Z_cand[row[found]], Z_train, y_train, sogp.classes[col[found]]
            )
        )
        entropy.append(replay.entropy[scored])
        decisive.append(replay.decisive[scored])
        no_task.append(replay.no_task[scored])
    return KindTimeFold(
        cr=correspondence_rates(np.concatenate(hits), np.concatenate(runs)),
        icad=np.concatenate(icad),
        rates=rates,
        entropy=np.concatenate(entropy),
        decisive=np.concatenate(decisive),
        no_task=np.concatenate(no_task),
    )


def kind_time_unseen(
    data: EvaluationData, pair: tuple[int, int], rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Introspection (Sec. 7.3.2, 7.4.3) of the kind-and-time recogniser trained on the
    pair of task types ``pair`` and replayed along every run of the others.

    Its SOGP is trained as in a fold (on the pair's way points, standardised on them,
    with their hard negatives; the first length-scale cap, claim thresholds playing no
    part), its prior on every tick of the pair's runs. Returns, at the other types' way
    points (the classifiers' introspection test points), the belief's normalised entropy
    (p,), whether it is decisive (p,) bool and its belief in no task (p,).
    """
    settings = data.settings
    wp = way_points_of(data.run, settings.stride)
    in_pair = np.isin(data.y, pair)
    train = wp[in_pair[wp]]
    scaler = FeatureScaler().fit(data.X_true[train])
    Z_cand = scaler.transform(data.X_cand)
    neg_rng, fit_rng = rng.spawn(2)
    neg = (
        hard_negatives(train, data.off, data.ids, data.target, settings.negatives_per_tick, neg_rng)
        if settings.negatives
        else np.zeros(0, dtype=int)
    )
    tick_of_cand = np.repeat(np.arange(len(data.off) - 1), np.diff(data.off))
    sogp = fit_method(
        "sogp",
        scaler.transform(data.X_true[train]),
        data.y[train],
        data.run[train],
        settings=settings,
        rng=fit_rng,
        negatives=Z_cand[neg],
        negative_groups=data.run[tick_of_cand[neg]],
        tune=False,
    )
    rec = KindTimeRecogniser(
        fit_prior(data, np.flatnonzero(in_pair), sogp.classes), settings.kind_time
    )
    entropy, decisive, no_task = [np.zeros(0)], [np.zeros(0, dtype=bool)], [np.zeros(0)]
    for ticks in runs_of(data, np.flatnonzero(~in_pair)):
        replay = replay_run(rec, run_means(sogp.model, Z_cand, data, ticks), data, ticks)
        at = way_points_of(data.run[ticks], settings.stride)
        entropy.append(replay.entropy[at])
        decisive.append(replay.decisive[at])
        no_task.append(replay.no_task[at])
    return np.concatenate(entropy), np.concatenate(decisive), np.concatenate(no_task)
