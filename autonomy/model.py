"""The contextual-task model file: everything the ``contextual_task`` mode needs, in one
``.npz`` (thesis Ch. 5-6, Sec. 7.4; spec sections 3-4; issue 3).

A :class:`ContextualModel` holds the feature scaler (7 encoded columns); the DP-GMM
motion clusters' means and covariances in the standardised encoded space (the
Mahalanobis stop, Eq. 6.3, Alg. 3; Sec. 6.2.1); per cluster the fast online GMR's
demonstration points (Alg. 2: ``s*`` [m] -> ``u*`` normalised, Sec. 5.1, 6.2.3); the
one-vs-all SOGP classifier over the clusters (Ch. 5); and metadata (versions, creation
date, SHA-256 of the training data, settings, cluster summary).

File layout (``numpy.savez``, loaded with ``allow_pickle=False``): the entry
``metadata`` is a JSON string (a 0-d unicode array); every other entry is a plain numeric
array named in :data:`ARRAYS` or, for the classifier, ``sogp.<field>`` and
``sogp.<j>.<field>`` for the GP of the j-th cluster. Choices where the thesis is
silent: docs/decisions.md.
"""

from __future__ import annotations

import io
import json
import zipfile
from dataclasses import dataclass, field
from importlib import metadata as _metadata
from pathlib import Path
from typing import Any

import numpy as np
from scipy.linalg import LinAlgError, cho_factor, cho_solve

from autonomy.features import ENCODED_NAMES, FeatureScaler
from autonomy.gp_kernel import se_ard_kernel
from autonomy.sogp_classifier import SOGPClassifier

FORMAT_VERSION = 2  # 2: angle encoded as |u_xy| (cos, sin)
DIM = len(ENCODED_NAMES)  # 7: s_x, s_y, cos theta, sin theta, v_x, v_y, omega
GMR_COLUMNS = ("s_x", "s_y", "v_x", "v_y", "omega")  # input s* [m], output u* (normalised)
GMR_INPUT = (0, 1)
GMR_OUTPUT = (2, 3, 4)
DEFAULT_MODEL = Path(__file__).resolve().parent / "models" / "default.npz"

# plain arrays of the file: name -> trailing shape ("c" clusters, "n" GMR points)
ARRAYS: dict[str, tuple[str, ...]] = {
    "scaler_mean": (str(DIM),),
    "scaler_scale": (str(DIM),),
    "cluster_ids": ("c",),
    "cluster_means": ("c", str(DIM)),
    "cluster_covariances": ("c", str(DIM), str(DIM)),
    "gmr_points": ("n", str(len(GMR_COLUMNS))),
    "gmr_offsets": ("c+1",),
}
_GP_SCALARS = (
    "capacity",
    "signal_var",
    "noise_var",
    "novelty_tol",
    "recondition_every",
    "n_updates",
)
_CLASSIFIER_SCALARS = ("capacity", "hyper_points", "restarts", "max_length_scale")


@dataclass(frozen=True, slots=True, eq=False)
class ContextualModel:
    """A trained contextual-task model (see the module docstring).

    ``cluster_ids[j]`` is the cluster id of row ``j`` of every per-cluster array and
    equals ``classifier.classes_[j]``; cluster ``j``'s GMR points are
    ``gmr_points[gmr_offsets[j]:gmr_offsets[j + 1]]``.
    """

    scaler: FeatureScaler
    cluster_ids: np.ndarray  # (c,) int
    cluster_means: np.ndarray  # (c, 7) standardised encoded features
    cluster_covariances: np.ndarray  # (c, 7, 7) same space
    gmr_points: np.ndarray  # (n, 5) s* [m] (robot frame), u* (normalised (-1, 1))
    gmr_offsets: np.ndarray  # (c + 1,) int
    sogp: dict[str, Any]  # SOGPClassifier.to_dict() without the GPs' "Q"
    metadata: dict[str, Any] = field(default_factory=dict)
    _cache: dict[str, Any] = field(default_factory=dict, repr=False)

    @classmethod
    def with_classifier(cls, classifier: SOGPClassifier, **fields: Any) -> ContextualModel:
        """A model around a fitted classifier (kept as is, ``Q`` included)."""
        d = classifier.to_dict()
        d["models"] = [{k: v for k, v in gp.items() if k != "Q"} for gp in d["models"]]
        model = cls(sogp=d, **fields)
        model._cache["classifier"] = classifier
        return model

    @property
    def classifier(self) -> SOGPClassifier:
        """The SOGP classifier, built on first use (its ``Q`` recomputed, see the module
        docstring); the contextual mode needs only :attr:`sogp`'s arrays."""
        clf = self._cache.get("classifier")
        if clf is None:
            d = dict(self.sogp)
            d["models"] = [
                {**gp, "Q": inverse_gram(gp["basis"], gp["length_scales"], gp["signal_var"])}
                for gp in self.sogp["models"]
            ]
            clf = self._cache["classifier"] = SOGPClassifier.from_dict(d)
        return clf

    @property
    def n_clusters(self) -> int:
        return int(self.cluster_ids.size)

    def cluster_names(self) -> tuple[str, ...]:
        """Display names of the clusters, ``"primitive_<id>"`` (no task labels)."""
        return tuple(f"primitive_{int(c)}" for c in self.cluster_ids)

    def cluster_points(self, j: int) -> np.ndarray:
        """(n_j, 5) GMR points of the cluster in row ``j``."""
        return self.gmr_points[int(self.gmr_offsets[j]) : int(self.gmr_offsets[j + 1])]


def platform_version() -> str:
    """The installed asa-study version, or ``"unknown"``."""
    try:
        return _metadata.version("asa-study")
    except _metadata.PackageNotFoundError:
        return "unknown"


# --------------------------------------------------------------------------- saving


def model_arrays(model: ContextualModel) -> dict[str, np.ndarray]:
    """Every entry of the model file, metadata included, as numpy arrays."""
    arrays: dict[str, np.ndarray] = {
        "scaler_mean": np.asarray(model.scaler.mean_, dtype=float),
        "scaler_scale": np.asarray(model.scaler.scale_, dtype=float),
        "cluster_ids": np.asarray(model.cluster_ids, dtype=np.int64),
        "cluster_means": np.asarray(model.cluster_means, dtype=float),
        "cluster_covariances": np.asarray(model.cluster_covariances, dtype=float),
        "gmr_points": np.asarray(model.gmr_points, dtype=float),
        "gmr_offsets": np.asarray(model.gmr_offsets, dtype=np.int64),
    }
    d = model.sogp
    for key in _CLASSIFIER_SCALARS:
        arrays[f"sogp.{key}"] = np.asarray(d[key])
    arrays["sogp.classes"] = np.asarray(d["classes"], dtype=np.int64)
    for j, gp in enumerate(d["models"]):
        for key in _GP_SCALARS:
            arrays[f"sogp.{j}.{key}"] = np.asarray(gp[key])
        arrays[f"sogp.{j}.length_scales"] = np.asarray(gp["length_scales"], dtype=float)
        arrays[f"sogp.{j}.basis"] = np.asarray(gp["basis"], dtype=float)
        arrays[f"sogp.{j}.alpha"] = np.asarray(gp["alpha"], dtype=float)
        C = np.asarray(gp["C"], dtype=float)
        arrays[f"sogp.{j}.C_upper"] = C[np.triu_indices(C.shape[0])]
    meta = dict(model.metadata)
    meta.setdefault("format_version", FORMAT_VERSION)
    arrays["metadata"] = np.array(json.dumps(meta, sort_keys=True))
    return arrays


def save_model(model: ContextualModel, path: str | Path) -> Path:
    """Write ``model`` to ``path`` (an ``.npz``; parent directories are created).

    Returns
    -------
    Path
        The path written.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    buffer = io.BytesIO()
    arrays = model_arrays(model)
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name in sorted(arrays):
            npy = io.BytesIO()
            value = np.asarray(arrays[name])  # not ascontiguousarray: it makes 0-d 1-d
            np.lib.format.write_array(
                npy, value if value.flags.c_contiguous else value.copy(), allow_pickle=False
            )
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            archive.writestr(info, npy.getvalue())
    path.write_bytes(buffer.getvalue())
    return path


# --------------------------------------------------------------------------- loading


def load_model(path: str | Path | None = None) -> ContextualModel:
    """Read and validate a model file (default: the shipped model).

    Raises
    ------
    ValueError
        Naming the file and the field: missing file, not an npz archive, missing entry,
        wrong shape or dtype, non-finite values, bad metadata, newer format version.
    """
    path = Path(DEFAULT_MODEL if path is None else path)
    if not path.is_file():
        raise ValueError(
            f"{path}: model file not found (train one with `asa train`; see "
            f"autonomy/models/README.md)"
        )
    try:
        # our own handle: np.load leaves its file open when the archive is corrupt
        with open(path, "rb") as handle, np.load(handle, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    except Exception as error:  # zip, format and pickle errors all mean a bad file
        raise ValueError(f"{path}: not a readable .npz model file ({error})") from None
    return model_from_arrays(arrays, where=str(path))


def _entry(arrays: dict[str, np.ndarray], name: str, where: str) -> np.ndarray:
    if name not in arrays:
        raise ValueError(f"{where}: field '{name}': missing")
    return arrays[name]


def _numeric(
    arrays: dict[str, np.ndarray],
    name: str,
    where: str,
    shape: tuple[int, ...],
    *,
    integer: bool = False,
) -> np.ndarray:
    a = _entry(arrays, name, where)
    kinds = "iu" if integer else "f"
    if a.dtype.kind not in kinds or a.shape != shape:
        expected = "integer" if integer else "float"
        raise ValueError(
            f"{where}: field '{name}': expected a {expected} array of shape {shape}, "
            f"got {a.dtype} {a.shape}"
        )
    if not integer and not np.all(np.isfinite(a)):
        raise ValueError(f"{where}: field '{name}': must be finite")
    return a


def _scalar(arrays: dict[str, np.ndarray], name: str, where: str) -> float | int:
    a = _entry(arrays, name, where)
    if a.shape != () or a.dtype.kind not in "iuf" or not np.isfinite(a):
        raise ValueError(f"{where}: field '{name}': expected a finite number, got {a!r}")
    return a.item()


def model_from_arrays(arrays: dict[str, np.ndarray], *, where: str = "model") -> ContextualModel:
    """Rebuild a :class:`ContextualModel` from :func:`model_arrays`' entries, validating
    every field (``where`` names the file in error messages)."""
    raw = _entry(arrays, "metadata", where)
    try:
        meta = json.loads(str(raw.item())) if raw.shape == () and raw.dtype.kind == "U" else None
    except json.JSONDecodeError:
        meta = None
    if not isinstance(meta, dict):
        raise ValueError(f"{where}: field 'metadata': must be a JSON object string")
    version = meta.get("format_version")
    if not isinstance(version, int):
        raise ValueError(f"{where}: field 'metadata.format_version': missing or not an integer")
    if version > FORMAT_VERSION:
        raise ValueError(
            f"{where}: field 'metadata.format_version': {version} is newer than this platform "
            f"reads ({FORMAT_VERSION}); upgrade asa-study or retrain the model"
        )
    if version < FORMAT_VERSION:
        raise ValueError(
            f"{where}: field 'metadata.format_version': {version} is an older feature "
            f"encoding than this platform reads ({FORMAT_VERSION}); retrain the model with "
            f"`asa train` (see autonomy/models/README.md)"
        )
    ids = _entry(arrays, "cluster_ids", where)
    if ids.ndim != 1 or ids.size < 1:
        raise ValueError(f"{where}: field 'cluster_ids': expected a non-empty 1-D array")
    c = ids.size
    ids = _numeric(arrays, "cluster_ids", where, (c,), integer=True)
    mean = _numeric(arrays, "scaler_mean", where, (DIM,))
    scale = _numeric(arrays, "scaler_scale", where, (DIM,))
    if np.any(scale <= 0):
        raise ValueError(f"{where}: field 'scaler_scale': must be positive")
    means = _numeric(arrays, "cluster_means", where, (c, DIM))
    covs = _numeric(arrays, "cluster_covariances", where, (c, DIM, DIM))
    try:
        np.linalg.cholesky(covs)
    except np.linalg.LinAlgError:
        raise ValueError(
            f"{where}: field 'cluster_covariances': must be symmetric positive definite"
        ) from None
    points = _entry(arrays, "gmr_points", where)
    n = points.shape[0] if points.ndim == 2 else -1
    points = _numeric(arrays, "gmr_points", where, (max(n, 0), len(GMR_COLUMNS)))
    offsets = _numeric(arrays, "gmr_offsets", where, (c + 1,), integer=True)
    if offsets[0] != 0 or offsets[-1] != n or np.any(np.diff(offsets) < 1):
        raise ValueError(
            f"{where}: field 'gmr_offsets': must rise strictly from 0 to {n} (every cluster "
            f"needs at least one GMR point)"
        )
    sogp = _sogp_from_arrays(arrays, where, c)
    if not np.array_equal(sogp["classes"], ids):
        raise ValueError(f"{where}: field 'sogp.classes': must equal 'cluster_ids'")
    scaler = FeatureScaler.from_dict({"mean": mean, "scale": scale})
    return ContextualModel(
        scaler=scaler,
        cluster_ids=ids.astype(np.int64),
        cluster_means=means,
        cluster_covariances=covs,
        gmr_points=points,
        gmr_offsets=offsets.astype(np.int64),
        sogp=sogp,
        metadata=meta,
    )


def _sogp_from_arrays(arrays: dict[str, np.ndarray], where: str, c: int) -> dict[str, Any]:
    d: dict[str, Any] = {key: _scalar(arrays, f"sogp.{key}", where) for key in _CLASSIFIER_SCALARS}
    d["classes"] = _numeric(arrays, "sogp.classes", where, (c,), integer=True)
    models = []
    for j in range(c):
        gp: dict[str, Any] = {key: _scalar(arrays, f"sogp.{j}.{key}", where) for key in _GP_SCALARS}
        ls = _numeric(arrays, f"sogp.{j}.length_scales", where, (DIM,))
        basis = _entry(arrays, f"sogp.{j}.basis", where)
        b = basis.shape[0] if basis.ndim == 2 else 0
        basis = _numeric(arrays, f"sogp.{j}.basis", where, (b, DIM))
        if b < 1:
            raise ValueError(f"{where}: field 'sogp.{j}.basis': needs at least one basis vector")
        alpha = _numeric(arrays, f"sogp.{j}.alpha", where, (b,))
        upper = _numeric(arrays, f"sogp.{j}.C_upper", where, (b * (b + 1) // 2,))
        if np.any(ls <= 0) or gp["signal_var"] <= 0 or gp["noise_var"] <= 0:
            raise ValueError(
                f"{where}: field 'sogp.{j}': length scales and variances must be positive"
            )
        C = np.zeros((b, b))
        C[np.triu_indices(b)] = upper
        C.T[np.triu_indices(b, 1)] = C[np.triu_indices(b, 1)]
        if int(gp["capacity"]) < b:
            raise ValueError(f"{where}: field 'sogp.{j}.basis': more rows than the capacity")
        gp.update(length_scales=ls, basis=basis, alpha=alpha, C=C)
        models.append(gp)
    d["models"] = models
    return d


def inverse_gram(basis: np.ndarray, length_scales: np.ndarray, signal_var: float) -> np.ndarray:
    """Inverse Gram matrix ``Q`` (b, b) of SOGP basis vectors (b, d), by Cholesky with a
    jitter of ``1e-10 * signal_var`` raised tenfold until it factors."""
    K = se_ard_kernel(basis, basis, length_scales=length_scales, signal_var=signal_var)
    eye = np.eye(K.shape[0])
    jitter = 1e-10 * signal_var
    for _ in range(12):
        try:
            factor = cho_factor(K + jitter * eye, lower=False, check_finite=False)
            Q = cho_solve(factor, eye, check_finite=False)
            return 0.5 * (Q + Q.T)
        except LinAlgError:
            jitter *= 10.0
    raise ValueError("sparse online GP basis: Gram matrix is not positive definite")
