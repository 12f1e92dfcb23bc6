"""Unsupervised training of the contextual-task model (thesis Sec. 6.2.1-6.2.3, 7.4.1;
issue 3, "Demonstrations and training"): DP-GMM motion primitives and the SOGP classifier
over them. Choices where the thesis is silent: docs/decisions.md.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from typing import Any

import numpy as np
from sklearn.mixture import BayesianGaussianMixture

from autonomy.features import ENCODED_NAMES, FeatureScaler, encode, task_features
from autonomy.intent_prior import demonstrated_prior
from autonomy.model import FORMAT_VERSION, ContextualModel, platform_version
from autonomy.sogp import MAX_LENGTH_SCALE
from autonomy.sogp_classifier import SOGPClassifier


@dataclass(frozen=True, slots=True)
class TrainSettings:
    """Settings of :func:`train` (choices: docs/decisions.md)."""

    max_components: int = 20  # upper bound of the DP-GMM's truncation
    restarts: int = 5  # DP-GMM inference runs; the highest lower bound is kept
    max_iter: int = 500  # variational EM iterations per run
    dpgmm_points: int = 6000  # subsample the DP-GMM is fitted on
    stride: int = 4  # way points: every 4th tick of a run (20 Hz -> 5 Hz, thesis Sec. 7.3)
    min_cluster_share: float = 0.04  # of all points; smaller clusters are merged
    min_cluster_points: int = 30
    capacity: int = 250  # SOGP basis vectors per cluster (thesis Sec. 7.3: 500)
    hyper_points: int = 300  # class-balanced subsample for the GP evidence
    hyper_restarts: int = 2  # L-BFGS-B runs per cluster
    gmr_k: int = 10  # neighbours of the fast online GMR (thesis Sec. 7.4.4)
    covariance_reg: float = 1e-2  # added to the primitives' covariance diagonal (std. units)
    max_length_scale: float = MAX_LENGTH_SCALE  # SOGP length-scale bound (std. units)
    candidates: int = 10  # nearest components a tick's hard negatives come from (the mode's)
    negatives_per_tick: int = 2  # other candidates per way point, target -1 in every GP
    refine: bool = True  # re-estimate each GP on its basis after the online pass

    def __post_init__(self) -> None:
        for name in (
            "max_components",
            "restarts",
            "max_iter",
            "dpgmm_points",
            "stride",
            "min_cluster_points",
            "capacity",
            "hyper_points",
            "hyper_restarts",
            "gmr_k",
            "candidates",
        ):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise ValueError(f"training setting {name}: must be an integer >= 1, got {value!r}")
        if not (isinstance(self.max_length_scale, int | float) and self.max_length_scale > 1e-2):
            raise ValueError(
                f"training setting max_length_scale: must be a number > 0.01, got "
                f"{self.max_length_scale!r}"
            )
        if not (isinstance(self.negatives_per_tick, int) and self.negatives_per_tick >= 0):
            raise ValueError(
                "training setting negatives_per_tick: must be an integer >= 0, got "
                f"{self.negatives_per_tick!r}"
            )
        if not (0.0 <= self.min_cluster_share < 1.0):
            raise ValueError(
                f"training setting min_cluster_share: must be in [0, 1), got "
                f"{self.min_cluster_share!r}"
            )


def data_sha256(q: np.ndarray) -> str:
    """SHA-256 of the training features (n, 6) as little-endian float64 bytes."""
    return hashlib.sha256(np.ascontiguousarray(q, dtype="<f8").tobytes()).hexdigest()


def cluster_dpgmm(
    Z: np.ndarray,
    *,
    settings: TrainSettings,
    rng: np.random.Generator,
    fit_rows: np.ndarray | None = None,
) -> tuple[np.ndarray, dict[str, Any]]:
    """DP-GMM clustering of standardised features with tiny clusters merged.

    scikit-learn's ``BayesianGaussianMixture`` (``weight_concentration_prior_type=
    "dirichlet_process"``, full covariances, at most ``max_components`` components,
    ``n_init`` = ``restarts``: the thesis "restarted inference many times and kept the
    highest evidence", Sec. 7.4.1).

    Parameters
    ----------
    Z : numpy.ndarray
        (n, d) standardised encoded features; every row is labelled.
    settings : TrainSettings
    rng : numpy.random.Generator
        Draws the fitting subsample and the mixture's seed.
    fit_rows : numpy.ndarray, optional
        Rows the mixture may be fitted on (default all); at most ``dpgmm_points`` of them
        are drawn.

    Returns
    -------
    labels : numpy.ndarray
        (n,) primitive ids 0..c-1, by decreasing size.
    info : dict
        ``components`` (used by the mixture), ``lower_bound``, ``converged``, ``dropped``
        (number of merged components), ``merged_points`` and ``fit_points``.
    """
    n = Z.shape[0]
    rows = np.arange(n) if fit_rows is None else np.asarray(fit_rows)
    fit_idx = np.sort(rng.choice(rows, size=min(len(rows), settings.dpgmm_points), replace=False))
    seed = int(rng.integers(2**31 - 1))
    bgm = BayesianGaussianMixture(
        n_components=min(settings.max_components, len(fit_idx)),
        covariance_type="full",
        weight_concentration_prior_type="dirichlet_process",
        n_init=settings.restarts,  # keeps the run with the highest lower bound
        max_iter=settings.max_iter,
        init_params="kmeans",
        random_state=seed,
    )
    bgm.fit(Z[fit_idx])
    resp = bgm.predict_proba(Z)  # (n, K)
    raw = np.argmax(resp, axis=1)
    counts = np.bincount(raw, minlength=resp.shape[1])
    threshold = max(settings.min_cluster_points, settings.min_cluster_share * n)
    keep = np.flatnonzero(counts >= threshold)
    if keep.size == 0:
        keep = np.array([int(np.argmax(counts))])
    assigned = keep[np.argmax(resp[:, keep], axis=1)]  # merge: most probable kept component
    sizes = np.bincount(assigned, minlength=resp.shape[1])[keep]
    order = keep[np.lexsort((keep, -sizes))]  # decreasing size, ties by index
    relabel = np.full(resp.shape[1], -1, dtype=np.int64)
    relabel[order] = np.arange(order.size)
    labels = relabel[assigned]
    info = {
        "components": int(np.count_nonzero(counts)),
        "lower_bound": float(bgm.lower_bound_),
        "converged": bool(bgm.converged_),
        "dropped": int(np.count_nonzero(counts) - keep.size),
        "merged_points": int(np.count_nonzero(~np.isin(raw, keep))),
        "fit_points": int(len(fit_idx)),
    }
    return labels, info


def way_points(n: int, run: np.ndarray | None, stride: int) -> np.ndarray:
    """Rows kept as way points: every ``stride``-th tick of each run (from its first)."""
    if run is None:
        return np.arange(0, n, stride)
    run = np.asarray(run)
    starts = np.concatenate(([True], run[1:] != run[:-1]))
    first = np.maximum.accumulate(np.where(starts, np.arange(n), 0))
    return np.flatnonzero((np.arange(n) - first) % stride == 0)


@dataclass(frozen=True, slots=True)
class DemoCandidates:
    """The semantic components around every demonstrated tick (robot frame).

    ``points[offsets[i]:offsets[i + 1]]`` (k_i, 2) [m] are tick ``i``'s candidates'
    target points with their ``ids``; ``target`` (n,) is the demonstrated component.
    """

    points: np.ndarray  # (m, 2) [m]
    offsets: np.ndarray  # (n + 1,) int
    ids: np.ndarray  # (m,) str
    target: np.ndarray  # (n,) str
    kinds: np.ndarray | None = None  # (m,) str the candidates' component kinds


def negative_features(
    q: np.ndarray,
    rows: np.ndarray,
    candidates: DemoCandidates,
    *,
    settings: TrainSettings,
    rng: np.random.Generator,
) -> np.ndarray:
    """Hard negatives: task features (Sec. 6.1) of components the driver did not target.

    At every tick of ``rows``, up to ``negatives_per_tick`` of the ``candidates`` nearest
    components (the mode's candidate set, Sec. 5.1) other than the demonstrated one, drawn
    at random, each with the tick's command ``q[i, 3:6]``.

    Returns
    -------
    numpy.ndarray
        (k, 6) task features.
    """
    off, pts, ids = candidates.offsets, candidates.points, candidates.ids
    out: list[np.ndarray] = []
    for i in np.asarray(rows):
        a, b = int(off[i]), int(off[i + 1])
        near = a + np.argsort(np.einsum("ij,ij->i", pts[a:b], pts[a:b]), kind="stable")
        near = near[: settings.candidates]
        wrong = near[ids[near] != candidates.target[i]]
        if len(wrong) > settings.negatives_per_tick:
            wrong = rng.choice(wrong, size=settings.negatives_per_tick, replace=False)
        if len(wrong):
            out.append(task_features(pts[np.sort(wrong)], q[i, 3:6]))
    return np.concatenate(out) if out else np.zeros((0, 6))


def fit_classifier(
    Z: np.ndarray,
    labels: np.ndarray,
    *,
    settings: TrainSettings,
    rng: np.random.Generator,
    negatives: np.ndarray | None = None,
) -> tuple[SOGPClassifier, list[float]]:
    """The SOGP classifier over the primitives.

    Returns
    -------
    classifier : SOGPClassifier
    novelty_tol : list of float
        (c,) the novelty tolerance of each cluster's GP (reported in the metadata).

    Raises
    ------
    ValueError
        If a GP ends with non-finite arrays (not seen since the SOGP's own guard against
        near-duplicate inputs, see :mod:`autonomy.sogp`).
    """
    clf = SOGPClassifier(
        capacity=settings.capacity,
        hyper_points=settings.hyper_points,
        restarts=settings.hyper_restarts,
        max_length_scale=settings.max_length_scale,
        refine=settings.refine,
    )
    clf.fit(Z, labels, rng=rng, negatives=negatives)
    for c, gp in zip(clf.classes_, clf.models_, strict=True):
        if not (np.all(np.isfinite(gp.alpha_)) and np.all(np.isfinite(gp.C_))):
            raise ValueError(
                f"training: the SOGP of primitive {int(c)} is numerically unstable on these data"
            )
    return clf, [float(gp.novelty_tol) for gp in clf.models_]


def cluster_summary(labels: np.ndarray, task: np.ndarray | None) -> list[dict[str, Any]]:
    """Per primitive: size and, if true task types are given, the share of each (reporting
    only)."""
    out = []
    for c in np.unique(labels):
        mask = labels == c
        entry: dict[str, Any] = {
            "id": int(c),
            "name": f"primitive_{int(c)}",
            "size": int(mask.sum()),
        }
        if task is not None:
            types, counts = np.unique(np.asarray(task)[mask], return_counts=True)
            entry["task_share"] = {
                str(t): round(float(k) / float(mask.sum()), 4)
                for t, k in sorted(zip(types, counts, strict=True), key=lambda x: -x[1])
            }
        out.append(entry)
    return out


def train(
    q: np.ndarray,
    *,
    seed: int = 0,
    settings: TrainSettings | None = None,
    task: np.ndarray | None = None,
    source: str = "",
    run: np.ndarray | None = None,
    candidates: DemoCandidates | None = None,
    executing: np.ndarray | None = None,
) -> ContextualModel:
    """Train a contextual-task model on unlabelled task features.

    Encode and standardise the features; cluster the way points with a DP-GMM
    (:func:`cluster_dpgmm`, Sec. 7.4.1), tiny clusters merged: the motion primitives;
    train the one-vs-all SOGP classifier over them (Ch. 5, :func:`fit_classifier`); keep
    per primitive the GMR points ``(s*, u*)`` (Alg. 2) and the mean and covariance of the
    rollout's Mahalanobis stop (Eq. 6.3). ``task`` serves only the cluster summary.

    Parameters
    ----------
    q : numpy.ndarray
        (n, 6) task features ``(s_x [m], s_y [m], theta [rad], v_x, v_y, omega)`` with the
        command in normalised (-1, 1) units, each against its demonstrated target.
    seed : int
        Seeds every random choice: one generator draws the DP-GMM subsample and seed
        and everything in the classifier, so the same data and seed give the same model.
    settings : TrainSettings, optional
    task : numpy.ndarray, optional
        (n,) true task types, for the cluster summary only.
    source : str
        Where the data came from (stored in the metadata).
    run : numpy.ndarray, optional
        (n,) run index of every row (rows of a run contiguous), for the way-point stride.
    candidates : DemoCandidates, optional
        The components around every row: the classifier learns the other components'
        features as hard negatives (:func:`negative_features`); without them it sees
        only the demonstrated targets.
    executing : numpy.ndarray, optional
        (n,) bool: the demonstrator was executing the task, not approaching it. With it
        and the candidates' kinds the metadata gets the kind-and-time recogniser's prior
        (:func:`autonomy.intent_prior.fit_intent_prior`, ``"intent_prior"``).

    Returns
    -------
    ContextualModel
        With metadata: versions, creation date, data hash, settings, cluster summary.
    """
    settings = TrainSettings() if settings is None else settings
    q = _checked_features(q, task)
    rng = np.random.default_rng(seed)
    X = encode(q)
    scaler = FeatureScaler().fit(X)
    Z = scaler.transform(X)
    wp = way_points(len(Z), run, settings.stride)
    labels, info = cluster_dpgmm(Z, settings=settings, rng=rng, fit_rows=wp)
    c = int(labels.max()) + 1
    means, covs, gmr_points, offsets = _primitive_statistics(q, Z, labels, settings)
    negatives = None
    if candidates is not None and settings.negatives_per_tick > 0:
        negatives = scaler.transform(
            encode(negative_features(q, wp, candidates, settings=settings, rng=rng))
        )
    classifier, tols = fit_classifier(
        Z[wp], labels[wp], settings=settings, rng=rng, negatives=negatives
    )
    info["negatives"] = 0 if negatives is None else int(len(negatives))
    info["truncation"] = int(settings.max_components)
    info["novelty_tol"] = tols
    info["way_points"] = int(len(wp))
    metadata = _metadata(q, labels, task, classifier, info, settings, seed=seed, source=source)
    if candidates is not None and candidates.kinds is not None and executing is not None:
        metadata["intent_prior"] = demonstrated_prior(q, labels, candidates, executing)
    return ContextualModel.with_classifier(
        classifier,
        scaler=scaler,
        cluster_ids=np.arange(c, dtype=np.int64),
        cluster_means=means,
        cluster_covariances=covs,
        gmr_points=gmr_points,
        gmr_offsets=offsets,
        metadata=metadata,
    )


def _metadata(
    q: np.ndarray,
    labels: np.ndarray,
    task: np.ndarray | None,
    classifier: SOGPClassifier,
    info: dict[str, Any],
    settings: TrainSettings,
    *,
    seed: int,
    source: str,
) -> dict[str, Any]:
    """The model's metadata: versions, date, data hash, settings, the DP-GMM's ``info``,
    the cluster summary, every GP's hyperparameters and (with ``task``) the purity."""
    metadata = {
        "format_version": FORMAT_VERSION,
        "platform_version": platform_version(),
        "created": datetime.now(UTC).isoformat(timespec="seconds"),
        "data_sha256": data_sha256(q),
        "n_points": int(q.shape[0]),
        "source": source,
        "seed": int(seed),
        "settings": asdict(settings),
        "dpgmm": info,
        "clusters": cluster_summary(labels, task),
        "hyperparameters": [_hyper_summary(hp) for hp in classifier.hyperparameters_],
    }
    if task is not None:
        metadata["purity"] = round(cluster_purity(labels, np.asarray(task)), 4)
    return metadata


def _hyper_summary(hp: Any) -> dict[str, Any]:
    """A GP's learnt hyperparameters for the model's metadata (JSON)."""
    return {
        "length_scales": [round(float(v), 6) for v in hp.length_scales],
        "signal_var": round(float(hp.signal_var), 6),
        "noise_var": round(float(hp.noise_var), 8),
        "log_evidence": round(float(hp.log_evidence), 3),
        "binding": list(hp.binding),
        "switched_off": [int(j) for j in hp.switched_off],
    }


def cluster_purity(labels: np.ndarray, task: np.ndarray) -> float:
    """Purity of the primitives with respect to the true task types: the share of points
    whose primitive's most common task type is their own (1 = every primitive holds one
    task type). ``labels`` and ``task`` (n,)."""
    total = 0
    for c in np.unique(labels):
        _, counts = np.unique(task[labels == c], return_counts=True)
        total += int(counts.max())
    return total / len(labels)


def _checked_features(q: np.ndarray, task: np.ndarray | None) -> np.ndarray:
    """``q`` as a float (n, 6) array of at least 20 finite rows, ``task`` of shape (n,)
    if given; ValueError naming them otherwise."""
    q = np.asarray(q, dtype=float)
    if q.ndim != 2 or q.shape[1] != 6:
        raise ValueError(f"training features q: expected shape (n, 6), got {q.shape}")
    if q.shape[0] < 20:
        raise ValueError(f"training features q: need at least 20 points, got {q.shape[0]}")
    if not np.all(np.isfinite(q)):
        raise ValueError("training features q: must be finite (no NaN or inf)")
    if task is not None and np.shape(task) != (q.shape[0],):
        raise ValueError(f"task labels: expected shape ({q.shape[0]},), got {np.shape(task)}")
    return q


def _primitive_statistics(
    q: np.ndarray, Z: np.ndarray, labels: np.ndarray, settings: TrainSettings
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per primitive ``0..c-1`` of ``labels`` (n,): the mean (c, 7) and regularised
    covariance (c, 7, 7) of its standardised features ``Z`` (n, 7) for the Mahalanobis
    stop (Eq. 6.3), and its GMR points (Alg. 2): rows ``(s_x, s_y, v_x, v_y, omega)`` of
    ``q`` (n, 6), primitive by primitive, with the (c + 1,) offsets of each block."""
    c = int(labels.max()) + 1
    means = np.empty((c, Z.shape[1]))
    covs = np.empty((c, Z.shape[1], Z.shape[1]))
    chunks = []
    for j in range(c):
        zj = Z[labels == j]
        means[j] = zj.mean(axis=0)
        d = zj - means[j]
        covs[j] = d.T @ d / len(zj) + settings.covariance_reg * np.eye(Z.shape[1])  # Eq. (6.3)
        chunks.append(q[labels == j][:, [0, 1, 3, 4, 5]])  # s* -> u* (Alg. 2)
    offsets = np.concatenate(([0], np.cumsum([len(ch) for ch in chunks]))).astype(np.int64)
    return means, covs, np.concatenate(chunks), offsets


SYNTHETIC_TASKS = ("doorway_crossing", "object_inspection", "wall_following")


def synthetic_demonstrations(
    rng: np.random.Generator,
    *,
    runs: int = 6,
    steps: int = 60,
    dt: float = 0.05,
    noise: float = 0.05,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Idealised demonstrations of three task patterns, for tests and benchmarks.

    A point robot (limits 1 m/s, 1.2 rad/s) driven by a noisy scripted stick, with the
    target point ``s`` in the robot frame:

    - ``doorway_crossing``: a target 1.5-3.5 m away within +-60 degrees of the heading;
      drive straight at it at 0.4-0.6 of full speed while turning to face it;
    - ``object_inspection``: a target about 1 m ahead; slide sideways (either direction)
      around it while turning to keep facing it;
    - ``wall_following``: a wall point 0.6-1 m to one side; drive forward along it.

    Runs alternate between the two sides (or directions) of each pattern.

    Parameters
    ----------
    rng : numpy.random.Generator
    runs : int
        Runs per pattern.
    steps : int
        Ticks per run.
    dt : float
        [s] tick.
    noise : float
        Std. dev. of the stick noise (normalised units).

    Returns
    -------
    q : numpy.ndarray
        (n, 6) task features, command normalised.
    task : numpy.ndarray
        (n,) pattern names (evaluation only).
    run : numpy.ndarray
        (n,) run index.
    """
    qs, tasks, run_ids = [], [], []
    r_id = 0
    for name in SYNTHETIC_TASKS:
        for k in range(runs):
            side = 1.0 if k % 2 == 0 else -1.0  # both sides and directions, alternately
            q_run = _synthetic_run(name, side, rng, steps=steps, dt=dt, noise=noise)
            qs += q_run
            tasks += [name] * len(q_run)
            run_ids += [r_id] * len(q_run)
            r_id += 1
    return np.array(qs), np.array(tasks), np.array(run_ids)


def _synthetic_run(
    name: str, side: float, rng: np.random.Generator, *, steps: int, dt: float, noise: float
) -> list[np.ndarray]:
    """One run of pattern ``name`` (see :func:`synthetic_demonstrations`): its (6,) task
    features tick by tick."""
    from autonomy.features import task_features  # local: keeps the module's imports light

    if name == "doorway_crossing":
        dist, bearing = rng.uniform(1.5, 3.5), side * rng.uniform(0.0, 1.0)
        target = dist * np.array([math.cos(bearing), math.sin(bearing)])
    elif name == "object_inspection":
        target = np.array([rng.uniform(0.8, 1.2), rng.uniform(-0.2, 0.2)])
    else:
        target = np.array([rng.uniform(-0.5, 0.5), side * rng.uniform(0.6, 1.0)])
    pose = np.zeros(3)
    speed = rng.uniform(0.4, 0.6)
    out = []
    for _ in range(steps):
        c, s = math.cos(pose[2]), math.sin(pose[2])
        d = target - pose[:2]
        sr = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])  # robot frame
        if name == "wall_following":
            # the wall point stays abeam: the nearest point of a wall along x
            target = np.array([pose[0], target[1]])
            d = target - pose[:2]
            sr = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])
        u = _synthetic_stick(name, sr, pose, side, speed)
        u = np.clip(u + noise * rng.standard_normal(3), -1.0, 1.0)
        out.append(task_features(sr, u)[0])
        vx, vy, w = u[0], u[1], 1.2 * u[2]
        pose = pose + dt * np.array([c * vx - s * vy, s * vx + c * vy, w])
        if name == "doorway_crossing" and np.hypot(*sr) < 0.3:
            break
    return out


def _synthetic_stick(
    name: str, sr: np.ndarray, pose: np.ndarray, side: float, speed: float
) -> np.ndarray:
    """The scripted stick (3,) of pattern ``name`` before noise, normalised units, for the
    target ``sr`` (2,) [m] in the robot frame and the robot's ``pose`` (3,) [m, m, rad]."""
    bearing = math.atan2(sr[1], sr[0])
    if name == "doorway_crossing":
        return np.array(
            [speed * math.cos(bearing), speed * math.sin(bearing), np.clip(1.5 * bearing, -1, 1)]
        )
    if name == "object_inspection":
        r = float(np.hypot(*sr))
        return np.array(
            [
                0.5 * (r - 1.0),
                side * speed,
                np.clip(2.0 * bearing - side * speed / max(r, 0.3), -1, 1),
            ]
        )
    return np.array([speed, 0.5 * (abs(sr[1]) - 0.8) * np.sign(sr[1]), -0.5 * math.sin(pose[2])])


def format_summary(model: ContextualModel) -> str:
    """What ``asa train`` prints: the DP-GMM's occupancy against its truncation, the
    primitives with their sizes, task shares and purity, and every GP's learnt
    hyperparameters (length scales in standard deviations of the encoded columns, ``off``
    for a switched-off dimension) with the bounds that bind."""
    meta = model.metadata
    info = meta.get("dpgmm", {})
    used, cap = info.get("components", "?"), info.get("truncation", "?")
    lines = [
        f"{meta.get('n_points', '?')} points, {info.get('way_points', '?')} way points, "
        f"{info.get('negatives', 0)} hard negatives",
        f"DP-GMM: {used} of {cap} components occupied"
        + (" (the truncation binds)" if used == cap else "")
        + f"; {info.get('dropped', 0)} below the size floor merged "
        f"({info.get('merged_points', 0)} points); {model.n_clusters} primitives",
    ]
    if "purity" in meta:
        lines.append(f"purity against the demonstrated task types: {meta['purity']:.2f}")
    for entry in meta.get("clusters", []):
        shares = ", ".join(f"{t} {100 * s:.0f}%" for t, s in entry.get("task_share", {}).items())
        lines.append(f"  {entry['name']:>12}: {entry['size']:6d} points  {shares}")
    names = ENCODED_NAMES
    lines.append("hyperparameters (Eq. 5.11): length scales " + " ".join(names))
    for entry, hp in zip(meta.get("clusters", []), meta.get("hyperparameters", []), strict=False):
        ls = [
            "off" if j in hp["switched_off"] else f"{v:.3g}"
            for j, v in enumerate(hp["length_scales"])
        ]
        binding = ", ".join(hp["binding"]) or "none"
        lines.append(
            f"  {entry['name']:>12}: {' '.join(ls)}; signal {hp['signal_var']:.3g}, "
            f"noise {hp['noise_var']:.3g}; bounds binding: {binding}"
        )
    return "\n".join(lines)
