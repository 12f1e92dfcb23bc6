"""Rerun recordings of trials: one ``.rrd`` per trial on a ``sim_time`` timeline.

The static map and semantic components, the robot pose and footprint, laser hits, ``u``
and ``v`` as arrows, ``beta`` and the recognition scores as time series, the predicted
trajectory, the recognised target, camera frames (front, and tail when the screen shows
it) as JPEG at a low rate, and the secondary task's questions and events as text
(DESIGN.md "Data"; issues 4, 19). Each trial has its own ``rr.RecordingStream``; entity
paths are the constants of :data:`ENTITY` (with the static scene in
:mod:`study.data.recording_scene`); modes return their diagnostics and the session
engine hands them to :meth:`TrialRecorder.tick`. Everything per tick is buffered and sent
in few large chunks (:class:`RecorderSettings`). Reading back, verifying and viewing:
:mod:`study.data.rrd`.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import io
import math
import uuid
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr

from sim.occupancy import OccupancyGrid
from sim.scenario import Scenario
from sim.types import SemanticComponent
from study.data.recording_scene import COLOURS, ENTITY, component_points, log_static

TIMELINE = "sim_time"  # duration timeline [s] of simulated trial time
RECORDING_NAMESPACE = uuid.UUID("5d1b7c0e-6f3a-4c1e-9a57-8a9d2f0e4b21")  # recording ids
_EPS_S = 1e-9  # [s] rounding tolerance of the rate schedules
_EVENT_LEVELS = {"collision": "WARN", "abort": "ERROR", "timeout": "WARN"}


@dataclass(frozen=True, slots=True)
class RecorderSettings:
    """What a :class:`TrialRecorder` logs and how often (change with ``dataclasses.replace``).

    Laser scans and camera frames are skipped while the robot stands still (moved less
    than ``still_m`` and ``still_rad`` since the last one logged): the scene is static,
    so they would repeat the last one (the baseline block, pauses).
    """

    flush_every_s: float = 60.0  # [s] simulated time between batched send_columns
    motion_hz: float = 10.0  # [Hz] pose, u, v, beta; >= the tick rate: every tick
    scores_hz: float = 5.0  # [Hz] the recognition scores (one series per candidate)
    laser_hz: float = 2.0  # [Hz] laser hits; <= 0 disables them
    laser_stride: int = 4  # every n-th hit of a scan (both lasers: 2 deg apart)
    path_hz: float = 5.0  # [Hz] predicted path; <= 0 disables it
    arrow_scale_s: float = 1.0  # [s] arrow length = scale * velocity
    jpeg_quality: int = 75  # camera frames; 0 stores them uncompressed
    camera_width_px: int = 160  # [px] wider frames are scaled down by a whole factor
    camera_hz: float = 0.0  # [Hz] frames :meth:`TrialRecorder.camera_due` asks for; 0: none
    still_m: float = 0.01  # [m] see the class docstring
    still_rad: float = 0.01  # [rad]

    def __post_init__(self) -> None:
        if not (math.isfinite(self.flush_every_s) and self.flush_every_s > 0):
            raise ValueError(f"recorder flush_every_s: must be > 0, got {self.flush_every_s!r}")
        if not 0 <= self.jpeg_quality <= 100:
            raise ValueError(f"recorder jpeg_quality: must be in 0..100, got {self.jpeg_quality}")
        if not all(math.isfinite(hz) and hz > 0 for hz in (self.motion_hz, self.scores_hz)):
            raise ValueError(
                f"recorder motion_hz, scores_hz: must be > 0, got {self.motion_hz!r}, "
                f"{self.scores_hz!r}"
            )
        if self.laser_stride < 1 or self.camera_width_px < 1:
            raise ValueError(
                f"recorder laser_stride, camera_width_px: must be >= 1, got "
                f"{self.laser_stride}, {self.camera_width_px}"
            )


def study_tag(protocol_sha256: str, seed: int, created_at: dt.datetime, study_id: int) -> str:
    """A study's short identity for file names: the first 8 hex digits of the SHA-256 of
    its protocol hash, seed, creation time (UTC, read back from the database) and row id.

    Recording files begin with it, so studies sharing a ``--recordings`` folder never
    name a file alike (issue 20).
    """
    when = created_at.replace(tzinfo=None).isoformat(sep=" ", timespec="microseconds")
    text = f"{protocol_sha256}:{seed}:{when}:{study_id}"
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:8]


def recording_id(trial_key: str) -> uuid.UUID:
    """Deterministic recording id of a trial: UUID5 of ``trial_key``."""
    return uuid.uuid5(RECORDING_NAMESPACE, trial_key)


# ------------------------------------------------------------------------ the recorder


def _next_time(scheduled: float, t: float, rate_hz: float) -> float:
    """Next due time [s] of a ``rate_hz`` stream just served at ``t``: on the schedule,
    or one period after ``t`` when the schedule has fallen behind (or not started)."""
    period = 1.0 / rate_hz
    due = scheduled + period
    return due if due > t + _EPS_S else t + period


def _moved(
    a: tuple[float, float, float] | None, b: tuple[float, float, float], s: RecorderSettings
) -> bool:
    """Whether pose ``b`` differs from ``a`` (x [m], y [m], yaw [rad]; ``a`` None: nothing
    logged yet) by ``s.still_m`` or ``s.still_rad``."""
    if a is None:
        return True
    turn = abs(math.remainder(b[2] - a[2], math.tau))
    return math.hypot(b[0] - a[0], b[1] - a[1]) >= s.still_m or turn >= s.still_rad


def _jpeg(frame: np.ndarray, width_px: int, quality: int) -> bytes:
    """An RGB frame (h, w, 3) uint8 as JPEG, scaled down by the smallest whole factor that
    makes it at most ``width_px`` wide (mean over factor x factor blocks)."""
    from PIL import Image  # rerun's own JPEG path uses Pillow too

    image = np.asarray(frame, dtype=np.uint8)
    k = -(-image.shape[1] // width_px)  # ceil
    if k > 1:
        h, w = image.shape[0] // k * k, image.shape[1] // k * k
        blocks = image[:h, :w].reshape(h // k, k, w // k, k, -1).mean(axis=(1, 3))
        image = np.rint(blocks).astype(np.uint8)
    out = io.BytesIO()
    Image.fromarray(image).save(out, format="JPEG", quality=quality)
    return out.getvalue()


class TrialRecorder:
    """Writes one trial to a rerun ``.rrd`` file.

    Parameters
    ----------
    path : str or Path
        The ``.rrd`` file to write (its folder is created; an existing file is replaced).
    trial_key : str
        Unique name of the trial (e.g. ``"P01/main/2"``); gives the recording id and name.
    scenario : Scenario
        The scene (obstacles, question region, robot footprint).
    components : sequence of SemanticComponent
        Map-frame semantic components (``sim.semantics.derive_components``).
    grid : OccupancyGrid
        The occupancy grid (``sim.occupancy.build_grid``), logged as the static map.
    application_id : str
        rerun application id.
    settings : RecorderSettings, optional
        Rates and sizes; defaults to ``RecorderSettings()``.

    Notes
    -----
    Call :meth:`tick` once per control tick with increasing ``t``, :meth:`event` and
    :meth:`question` as things happen, and :meth:`close` at the end (or use the
    recorder as a context manager). Nothing is sent over a network.
    """

    def __init__(
        self,
        path: str | Path,
        *,
        trial_key: str,
        scenario: Scenario,
        components: Sequence[SemanticComponent],
        grid: OccupancyGrid,
        application_id: str = "asa-study",
        settings: RecorderSettings | None = None,
    ) -> None:
        self.path = Path(path)
        self.trial_key = trial_key
        self.settings = settings if settings is not None else RecorderSettings()
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._components = {c.id: c for c in components}
        self._rec = rr.RecordingStream(
            application_id, recording_id=recording_id(trial_key), send_properties=True
        )
        self._rec.save(self.path)
        self._rec.set_log_time_enabled(False)
        self._rec.set_log_tick_enabled(False)
        self._rec.send_recording_name(trial_key)
        self._closed = False
        self._target_state: tuple[str, str] | None = None
        self._next_flush = math.nan
        self._next_laser = -math.inf
        self._next_path = -math.inf
        self._next_camera = -math.inf
        self._next_motion = -math.inf
        self._next_scores = -math.inf
        self._last_motion: tuple[tuple[Any, ...], float | None] | None = None  # not yet kept
        self._laser_pose: tuple[float, float, float] | None = None  # last scan logged here
        self._camera_pose: tuple[float, float, float] | None = None  # last frame logged here
        self._reset_buffers()
        log_static(self._rec, scenario, components, grid)

    # -------------------------------------------------------------- per tick

    def _reset_buffers(self) -> None:
        self._t: list[float] = []
        self._pose: list[tuple[float, float, float]] = []
        self._u: list[tuple[float, float]] = []
        self._v: list[tuple[float, float]] = []
        self._beta_t: list[float] = []
        self._beta: list[float] = []
        self._scores: dict[str, tuple[list[float], list[float]]] = {}
        self._path_t: list[float] = []
        self._path: list[np.ndarray] = []
        self._laser_t: list[float] = []
        self._laser: list[np.ndarray] = []
        self._target_t: list[float] = []
        self._target: list[np.ndarray] = []  # (k, 2) float32 map frame; (0, 2): none
        self._target_labels: list[str] = []  # k per target, concatenated
        self._frames: dict[str, tuple[list[float], list[bytes]]] = {}  # entity -> JPEGs

    def tick(
        self,
        t: float,
        pose: Any,
        points: np.ndarray | None,
        u: np.ndarray,
        v: np.ndarray,
        assist: Any | None = None,
        camera: np.ndarray | None = None,
        tail_camera: np.ndarray | None = None,
    ) -> None:
        """Record one control tick.

        Parameters
        ----------
        t : float
            Simulated trial time [s], increasing.
        pose : Pose2D-like
            True robot pose in the map frame (``x`` [m], ``y`` [m], ``yaw`` [rad]).
        points : ndarray, shape (m, 2), or None
            Laser hits in the ROBOT frame [m] (``Observation.points``); every
            ``settings.laser_stride``-th kept at ``settings.laser_hz`` while the robot moves.
        u, v : ndarray, shape (3,)
            Joystick command and command sent to the robot, robot frame
            (v_x [m/s], v_y [m/s], omega [rad/s]).
        assist : Assist-like, optional
            Diagnostics of the mode: ``beta``, ``label``, ``target``, ``scores``
            (name -> number) and ``predicted_path`` (k, 3) robot frame. ``None``
            for ticks without a mode (e.g. the baseline block).
        camera, tail_camera : ndarray, shape (h, w, 3) uint8, optional
            Front and tail camera frames, logged as JPEG when given (the caller picks the
            rate, e.g. by :meth:`camera_due`).
        """
        if self._closed:
            raise RuntimeError(f"{self.path}: recorder is closed")
        t = float(t)
        if math.isnan(self._next_flush):
            self._next_flush = t + self.settings.flush_every_s
        xy_yaw = (float(pose.x), float(pose.y), float(pose.yaw))
        motion = (t, xy_yaw, (float(u[0]), float(u[1])), (float(v[0]), float(v[1])))
        beta = float(assist.beta) if assist is not None else None
        self._last_motion = None
        if t >= self._next_motion - _EPS_S:
            self._next_motion = _next_time(self._next_motion, t, self.settings.motion_hz)
            self._buffer_motion(motion, beta)
        else:  # kept until the next tick: the last tick of a trial is always recorded
            self._last_motion = (motion, beta)
        if points is not None:
            self._buffer_laser(t, xy_yaw, points)
        if assist is not None:
            self._buffer_assist(t, pose, assist)
        for entity, frame in ((ENTITY.camera, camera), (ENTITY.tail_camera, tail_camera)):
            if frame is not None:
                self._buffer_frame(t, entity, frame)
        if camera is not None or tail_camera is not None:
            self._camera_pose = xy_yaw
            if self.settings.camera_hz > 0:
                self._next_camera = _next_time(self._next_camera, t, self.settings.camera_hz)
        if t >= self._next_flush - _EPS_S:
            self._flush_buffers()
            self._next_flush = t + self.settings.flush_every_s

    def camera_due(self, t: float, pose: Any) -> bool:
        """Whether a camera frame at ``t`` [s] and ``pose`` would be logged: one per
        ``settings.camera_hz`` period, none while the robot stands still."""
        s = self.settings
        if s.camera_hz <= 0 or float(t) < self._next_camera - _EPS_S:
            return False
        return _moved(self._camera_pose, (float(pose.x), float(pose.y), float(pose.yaw)), s)

    def _buffer_laser(self, t: float, xy_yaw: tuple[float, float, float], points: Any) -> None:
        s = self.settings
        if s.laser_hz <= 0 or t < self._next_laser - _EPS_S:
            return
        if not _moved(self._laser_pose, xy_yaw, s):
            return  # standing still: the last scan shows the same
        self._laser_t.append(t)
        self._laser.append(np.array(points, dtype=np.float32).reshape(-1, 2)[:: s.laser_stride])
        self._laser_pose = xy_yaw
        self._next_laser = _next_time(self._next_laser, t, s.laser_hz)

    def _buffer_motion(self, motion: tuple[Any, ...], beta: float | None) -> None:
        """Pose, ``u``, ``v`` (and ``beta``, with a mode) of one tick."""
        t, xy_yaw, u, v = motion
        self._t.append(t)
        self._pose.append(xy_yaw)
        self._u.append(u)
        self._v.append(v)
        if beta is not None:
            self._beta_t.append(t)
            self._beta.append(beta)

    def _buffer_assist(self, t: float, pose: Any, assist: Any) -> None:
        if t >= self._next_scores - _EPS_S:
            self._next_scores = _next_time(self._next_scores, t, self.settings.scores_hz)
            for key, value in assist.scores.items():
                times, values = self._scores.setdefault(key, ([], []))
                times.append(t)
                values.append(float(value))
        if self.settings.path_hz > 0 and t >= self._next_path - _EPS_S:
            self._path_t.append(t)
            self._path.append(self._path_in_map(pose, assist.predicted_path))
            self._next_path = _next_time(self._next_path, t, self.settings.path_hz)
        state = (str(assist.target), str(assist.label))
        if state != self._target_state:
            self._log_target(t, state)

    def _buffer_frame(self, t: float, entity: str, frame: np.ndarray) -> None:
        s = self.settings
        if s.jpeg_quality == 0:  # uncompressed: logged at once
            self._rec.set_time(TIMELINE, duration=t)
            self._rec.log(entity, rr.Image(np.asarray(frame)))
            return
        times, blobs = self._frames.setdefault(entity, ([], []))
        times.append(t)
        blobs.append(_jpeg(frame, s.camera_width_px, s.jpeg_quality))

    @staticmethod
    def _path_in_map(pose: Any, path: np.ndarray) -> np.ndarray:
        p = np.asarray(path, dtype=float).reshape(-1, 3)
        c, s = math.cos(pose.yaw), math.sin(pose.yaw)
        return np.column_stack(
            (c * p[:, 0] - s * p[:, 1] + pose.x, s * p[:, 0] + c * p[:, 1] + pose.y)
        ).astype(np.float32)

    def _log_target(self, t: float, state: tuple[str, str]) -> None:
        """Buffer a change of the highlighted target (sent with the next batch)."""
        self._target_state = state
        target, label = state
        component = self._components.get(target)
        self._target_t.append(t)
        if component is None:
            # no target, or an id the scene does not know: nothing highlighted
            self._target.append(np.empty((0, 2), dtype=np.float32))
            return
        pts = component_points(component).astype(np.float32)
        text = f"{target} ({label})" if label else target
        self._target.append(pts)
        self._target_labels += [text] + [""] * (len(pts) - 1)

    def _flush_motion(self) -> None:
        """Send the buffered robot poses and the ``u`` and ``v`` arrows."""
        rec = self._rec
        times = [rr.TimeColumn(TIMELINE, duration=np.asarray(self._t))]
        pose = np.asarray(self._pose)
        n = len(pose)
        half = pose[:, 2] / 2
        rec.send_columns(
            ENTITY.robot,
            indexes=times,
            columns=rr.Transform3D.columns(
                translation=np.column_stack((pose[:, :2], np.zeros(n))),
                quaternion=np.column_stack((np.zeros(n), np.zeros(n), np.sin(half), np.cos(half))),
            ),
        )
        scale = self.settings.arrow_scale_s
        for entity, values in ((ENTITY.u, self._u), (ENTITY.v, self._v)):
            rec.send_columns(
                entity,
                indexes=times,
                # origins default to the robot's centre
                columns=rr.Arrows2D.columns(vectors=scale * np.asarray(values)),
            )

    def _flush_buffers(self) -> None:
        rec = self._rec
        if self._t:
            self._flush_motion()
        if self._beta:
            rec.send_columns(
                ENTITY.beta,
                indexes=[rr.TimeColumn(TIMELINE, duration=np.asarray(self._beta_t))],
                columns=rr.Scalars.columns(scalars=np.asarray(self._beta)),
            )
        for key, (times_s, values) in self._scores.items():
            rec.send_columns(
                ENTITY.score(key),
                indexes=[rr.TimeColumn(TIMELINE, duration=np.asarray(times_s))],
                columns=rr.Scalars.columns(scalars=np.asarray(values)),
            )
        if self._path:
            # one send: a (rows, k, 2) array when every path has k points (the fastest to
            # convert), else the list (cheaper than one send per length; docs/results.md)
            same = len({len(p) for p in self._path}) == 1
            rec.send_columns(
                ENTITY.predicted_path,
                indexes=[rr.TimeColumn(TIMELINE, duration=np.asarray(self._path_t))],
                columns=rr.LineStrips2D.columns(
                    strips=np.stack(self._path) if same else self._path
                ),
            )
        if self._target:
            rec.send_columns(
                ENTITY.target,
                indexes=[rr.TimeColumn(TIMELINE, duration=np.asarray(self._target_t))],
                columns=rr.Points2D.columns(
                    positions=np.concatenate(self._target), labels=self._target_labels
                ).partition([len(p) for p in self._target]),
            )
        if self._laser:
            rec.send_columns(
                ENTITY.laser,
                indexes=[rr.TimeColumn(TIMELINE, duration=np.asarray(self._laser_t))],
                columns=rr.Points2D.columns(positions=np.concatenate(self._laser)).partition(
                    [len(p) for p in self._laser]
                ),
            )
        for entity, (times_s, blobs) in self._frames.items():
            rec.send_columns(
                entity,
                indexes=[rr.TimeColumn(TIMELINE, duration=np.asarray(times_s))],
                columns=rr.EncodedImage.columns(blob=blobs, media_type=["image/jpeg"] * len(blobs)),
            )
        self._reset_buffers()

    # -------------------------------------------------------------- text

    def event(self, t: float, kind: str, text: str = "") -> None:
        """An event of the trial (collision, dock, inspection, region entry, ...) at ``t`` [s]."""
        if self._closed:
            raise RuntimeError(f"{self.path}: recorder is closed")
        self._rec.set_time(TIMELINE, duration=float(t))
        message = f"{kind}: {text}" if text else kind
        self._rec.log(ENTITY.events, rr.TextLog(message, level=_EVENT_LEVELS.get(kind, "INFO")))

    def question(self, t: float, text: str) -> None:
        """A secondary-task question shown (or answered) at ``t`` [s]."""
        if self._closed:
            raise RuntimeError(f"{self.path}: recorder is closed")
        self._rec.set_time(TIMELINE, duration=float(t))
        self._rec.log(ENTITY.questions, rr.TextLog(text))

    # -------------------------------------------------------------- end

    def close(self) -> None:
        """Send what is buffered, flush to disk and close the file (idempotent)."""
        if self._closed:
            return
        if self._last_motion is not None:
            self._buffer_motion(*self._last_motion)
        self._flush_buffers()
        self._rec.flush()
        self._rec.disconnect()
        self._closed = True

    def __enter__(self) -> TrialRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class NoRecording:
    """Stands in for :class:`TrialRecorder` when a trial is not recorded (``asa synth
    --no-recordings``): every call does nothing and no camera frame is ever due."""

    def tick(self, *args: Any, **kwargs: Any) -> None:
        """Nothing to record."""

    def camera_due(self, t: float, pose: Any) -> bool:
        return False

    def event(self, t: float, kind: str, text: str = "") -> None:
        """Nothing to record."""

    def question(self, t: float, text: str) -> None:
        """Nothing to record."""

    def close(self) -> None:
        """Nothing to close."""


__all__ = [
    "COLOURS",
    "ENTITY",
    "RECORDING_NAMESPACE",
    "TIMELINE",
    "NoRecording",
    "RecorderSettings",
    "TrialRecorder",
    "recording_id",
]
