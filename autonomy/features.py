"""Task features of the contextual-task mode (thesis Sec. 5.1 and 6.1).

A task feature ``q = (s_x, s_y, theta, v_x, v_y, omega)`` joins the intentional target
point ``s`` of one candidate semantic component (robot frame, metres) with the user's
command ``u = (v_x, v_y, omega)`` (each channel normalised to (-1, 1), Sec. 5.1) and the
angle ``theta`` between the translational input ``u_xy = (v_x, v_y)`` and the vector
``r_s`` from the robot centre to ``s`` (Sec. 6.1). For learning, the angle is encoded as
``|u_xy| (cos theta, sin theta)`` -- the translational input expressed in a frame whose
x axis points at the target -- so that +-pi are neighbours (issue 3) and the encoding is
continuous, with the defined value ``(0, 0)`` when there is no translational input; every
column is then standardised with a :class:`FeatureScaler` learnt on the training data.
Choices where the thesis is silent: docs/decisions.md.
"""

from __future__ import annotations

from typing import Any

import numpy as np

FEATURE_NAMES: tuple[str, ...] = ("s_x", "s_y", "theta", "v_x", "v_y", "omega")
ENCODED_NAMES: tuple[str, ...] = (
    "s_x",
    "s_y",
    "speed_cos_theta",
    "speed_sin_theta",
    "v_x",
    "v_y",
    "omega",
)


def wrap_angle(a: np.ndarray | float) -> np.ndarray:
    """Wrap angles to (-pi, pi].

    Parameters
    ----------
    a : array_like
        Angles [rad], any shape.

    Returns
    -------
    numpy.ndarray
        Same shape, in (-pi, pi] [rad].
    """
    w = np.arctan2(np.sin(a), np.cos(a))
    # arctan2 returns -pi for angles on the negative real axis; the interval is half-open.
    return np.where(w <= -np.pi, np.pi, w)


def task_features(
    targets: np.ndarray,
    u: np.ndarray,
    *,
    min_speed: float = 1e-6,
    min_distance: float = 1e-9,
) -> np.ndarray:
    """Task features of every candidate target for one user command (Sec. 6.1).

    Parameters
    ----------
    targets : numpy.ndarray
        (m, 2) intentional target points ``s`` in the robot frame [m], one per candidate
        semantic component; a single (2,) point is accepted too.
    u : numpy.ndarray
        (3,) user command ``(v_x, v_y, omega)``, normalised to (-1, 1).
    min_speed : float
        Below this norm of ``(v_x, v_y)`` the input has no direction and ``theta = 0``.
    min_distance : float
        Below this norm of ``s`` [m] the target has no direction and ``theta = 0``.

    Returns
    -------
    numpy.ndarray
        (m, 6) features ``(s_x, s_y, theta, v_x, v_y, omega)``; ``theta`` [rad] in (-pi, pi].
    """
    s = np.atleast_2d(np.asarray(targets, dtype=float))
    u = np.asarray(u, dtype=float)
    if s.ndim != 2 or s.shape[1] != 2:
        raise ValueError(f"targets: expected shape (m, 2), got {np.shape(targets)}")
    if u.shape != (3,):
        raise ValueError(f"u: expected shape (3,) (v_x, v_y, omega), got {u.shape}")
    m = s.shape[0]
    q = np.empty((m, 6))
    q[:, 0:2] = s
    speed = np.hypot(u[0], u[1])
    dist = np.hypot(s[:, 0], s[:, 1])
    theta = wrap_angle(np.arctan2(u[1], u[0]) - np.arctan2(s[:, 1], s[:, 0]))  # Sec. 6.1
    defined = (dist >= min_distance) & (speed >= min_speed)
    q[:, 2] = np.where(defined, theta, 0.0)
    q[:, 3:6] = u
    return q


def encode(q: np.ndarray) -> np.ndarray:
    """The learning representation of task features: the angle as ``|u_xy| (cos, sin)``.

    Parameters
    ----------
    q : numpy.ndarray
        (m, 6) task features from :func:`task_features` (or a single (6,) feature).

    Returns
    -------
    numpy.ndarray
        (m, 7) ``(s_x, s_y, |u_xy| cos theta, |u_xy| sin theta, v_x, v_y, omega)`` with
        ``|u_xy| = hypot(v_x, v_y)`` (normalised units), or (7,) for a single feature;
        ``(0, 0)`` in columns 2-3 when ``|u_xy| = 0``.
    """
    q = np.asarray(q, dtype=float)
    single = q.ndim == 1
    q2 = np.atleast_2d(q)
    if q2.ndim != 2 or q2.shape[1] != 6:
        raise ValueError(f"q: expected shape (m, 6) {FEATURE_NAMES}, got {q.shape}")
    out = np.empty((q2.shape[0], 7))
    out[:, 0:2] = q2[:, 0:2]
    speed = np.hypot(q2[:, 3], q2[:, 4])
    out[:, 2] = speed * np.cos(q2[:, 2])
    out[:, 3] = speed * np.sin(q2[:, 2])
    out[:, 4:7] = q2[:, 3:6]
    return out[0] if single else out


class FeatureScaler:
    """Standardisation ``(x - mean_) / scale_`` learnt on training data.

    Attributes
    ----------
    mean_ : numpy.ndarray
        (d,) column means of the training data.
    scale_ : numpy.ndarray
        (d,) column standard deviations (ddof 0); 1 where a column is constant.
    """

    mean_: np.ndarray
    scale_: np.ndarray

    def __init__(self, *, min_scale: float = 1e-12) -> None:
        self.min_scale = min_scale

    def fit(self, X: np.ndarray) -> FeatureScaler:
        """Learn the column means and standard deviations of ``X`` (n, d), n >= 1."""
        X = np.asarray(X, dtype=float)
        if X.ndim != 2 or X.shape[0] < 1:
            raise ValueError(f"X: expected a non-empty (n, d) array, got shape {X.shape}")
        if not np.all(np.isfinite(X)):
            raise ValueError("X: features must be finite (no NaN or inf)")
        self.mean_ = X.mean(axis=0)
        std = X.std(axis=0)
        self.scale_ = np.where(std > self.min_scale, std, 1.0)
        return self

    def transform(self, X: np.ndarray) -> np.ndarray:
        """Standardise ``X`` (n, d) or (d,); same shape out."""
        self._check_fitted()
        return (np.asarray(X, dtype=float) - self.mean_) / self.scale_

    def fit_transform(self, X: np.ndarray) -> np.ndarray:
        """:meth:`fit` then :meth:`transform`."""
        return self.fit(X).transform(X)

    def inverse_transform(self, Z: np.ndarray) -> np.ndarray:
        """Undo :meth:`transform`: ``Z * scale_ + mean_``."""
        self._check_fitted()
        return np.asarray(Z, dtype=float) * self.scale_ + self.mean_

    def to_dict(self) -> dict[str, Any]:
        """Arrays and settings for a model file."""
        self._check_fitted()
        return {
            "min_scale": float(self.min_scale),
            "mean": self.mean_.copy(),
            "scale": self.scale_.copy(),
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> FeatureScaler:
        """Rebuild from :meth:`to_dict`; ValueError naming the field if it is malformed."""
        for key in ("mean", "scale"):
            if key not in d:
                raise ValueError(f"feature scaler: missing field '{key}'")
        mean = np.asarray(d["mean"], dtype=float)
        scale = np.asarray(d["scale"], dtype=float)
        if mean.ndim != 1 or scale.shape != mean.shape:
            raise ValueError(
                f"feature scaler: 'mean' and 'scale' must be 1-D of equal length, got "
                f"{mean.shape} and {scale.shape}"
            )
        if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(scale)) and np.all(scale > 0)):
            raise ValueError("feature scaler: 'mean' must be finite and 'scale' positive")
        out = cls(min_scale=float(d.get("min_scale", 1e-12)))
        out.mean_ = mean.copy()
        out.scale_ = scale.copy()
        return out

    def _check_fitted(self) -> None:
        if not hasattr(self, "mean_"):
            raise RuntimeError("FeatureScaler is not fitted; call fit() first")
