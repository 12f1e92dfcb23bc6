"""The lab's streams on the session's clock (DESIGN.md, "The lab's clock"): the one module
where clocks are converted.

Clocks: a stream's timestamps are its own LSL clock; ``session_clock_s`` is the
``pylsl.local_clock()`` of the machine that ran the session [s], which every tick stores
(``sample.lsl_clock_s``); ``trial_t_s`` is a trial's simulated time [s]. A stream's
timestamps reach the session's clock through its clock offsets, fitted per segment (one
connection of the stream) as LabRecorder's readers do (pyxdf's ``_clock_sync``: a robust
linear fit of the offsets over the time they were measured, Huber-like with a winsorising
threshold of 0.1 ms, by ADMM), plus an imported file's shift (``lsl_stream.clock_shift_s``).
The session's clock reaches a trial's time through its ticks (piecewise linear between
ticks, slope 1 beyond them).
"""

from __future__ import annotations

import base64
import json
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import pandas as pd

LSL_TABLES: tuple[str, ...] = ("lsl_stream", "lsl_chunk", "lsl_offset", "lsl_gap")
WINSOR_S = 1e-4  # [s] pyxdf's winsor_threshold
TRIAL_MARGIN_S = 0.05  # [s] before a trial's first tick that still belongs to it (one tick)


def robust_fit(A: np.ndarray, y: np.ndarray, rho: float = 1.0, iters: int = 1000) -> np.ndarray:
    """A robust linear regression, ``minimize 1/2 sum(huber(A x - y))`` by ADMM, as pyxdf's
    ``_robust_fit`` (Boyd et al. 2011, "Distributed optimization and statistical learning
    via ADMM", Sec. 6.1; Huber's threshold 1 in the units of ``y``).

    Parameters
    ----------
    A : (n, 2) array
        Design matrix (a column of ones, the times).
    y : (n,) array
        Observations.
    """
    A = np.array(A, dtype=float)
    shift = float(np.min(A[:, 1]))
    A[:, 1] -= shift  # conditioning: times near zero
    Aty = A.T @ y
    L = np.linalg.cholesky(A.T @ A)
    U = L.T
    z = np.zeros_like(y)
    u = z
    x = np.zeros(A.shape[1])
    for _ in range(iters):
        x = np.linalg.solve(U, np.linalg.solve(L, Aty + A.T @ (z - u)))
        d = A @ x - y + u
        d_inv = np.divide(1.0, d, out=np.zeros_like(d), where=d != 0)
        tmp = np.maximum(0.0, 1.0 - (1.0 + 1.0 / rho) * np.abs(d_inv))
        z = rho / (1.0 + rho) * d + 1.0 / (1.0 + rho) * tmp * d
        u = d - z
    x[0] -= x[1] * shift
    return x


def fit_offsets(
    clock_s: np.ndarray, offset_s: np.ndarray, winsor_s: float = WINSOR_S
) -> tuple[float, float]:  # noqa: E501
    """``(a, b)`` with ``offset(ts) = a + b ts`` [s] fitted to the clock offsets measured at
    ``clock_s``; one offset: a constant; none: zero. In pyxdf: ``load_xdf(...,
    synchronize_clocks=True)`` without clock-reset handling."""
    clock_s, offset_s = np.asarray(clock_s, float), np.asarray(offset_s, float)
    if len(clock_s) == 0:
        return 0.0, 0.0
    if len(clock_s) == 1 or np.ptp(clock_s) == 0:
        return float(np.median(offset_s)), 0.0
    # pyxdf scales the times and offsets, not the intercept's column, by the threshold
    A = np.column_stack([np.ones(len(clock_s)), clock_s / winsor_s])
    a, b = robust_fit(A, offset_s / winsor_s)
    return float(a * winsor_s), float(b)


def corrected(timestamps_s: np.ndarray, clock_s: np.ndarray, offset_s: np.ndarray) -> np.ndarray:
    """A stream's timestamps [s, its clock] on the clock its offsets were measured against
    (an XDF file's: the recorder's), the offsets fitted by :func:`fit_offsets`."""
    ts = np.asarray(timestamps_s, dtype=float)
    a, b = fit_offsets(clock_s, offset_s)
    return ts + a + b * ts


def decode(blob: bytes | str, dtype: str, channels: int) -> np.ndarray:
    """A chunk's stored values (``lsl_chunk.data``; base64 text from a CSV export) as
    ``(n, channels)``: float64, int64, or object for string streams."""
    raw = base64.b64decode(blob) if isinstance(blob, str) else bytes(blob)
    if dtype == "json":
        return np.array(json.loads(raw.decode("utf-8")), dtype=object).reshape(-1, channels)
    return np.frombuffer(raw, dtype="<" + dtype).reshape(-1, channels)


def timestamps(blob: bytes | str) -> np.ndarray:
    """A chunk's timestamps (``lsl_chunk.timestamps``) [s, the stream's clock]."""
    raw = base64.b64decode(blob) if isinstance(blob, str) else bytes(blob)
    return np.frombuffer(raw, dtype="<f8")


@dataclass(frozen=True, slots=True)
class Aligned:
    """A study's streams, ticks and events on the session's clock.

    Attributes
    ----------
    streams : stream id -> DataFrame (``segment``, ``timestamp`` [s, stream clock],
        ``session_clock_s``, ``trial_id``, ``trial_t_s``, one column per channel label).
    ticks : ``trial_id``, ``tick``, ``t`` [s simulated], ``session_clock_s``.
    events : the event table's rows of trials with ticks, with ``session_clock_s``.
    offsets : per stream and segment, ``a``, ``b`` of the fit, ``n`` offsets, their
        ``spread_ms`` (max - min) and the fit's residual ``resid_ms`` (max |.|).
    """

    streams: dict[int, pd.DataFrame]
    ticks: pd.DataFrame
    events: pd.DataFrame
    offsets: pd.DataFrame


def tick_clocks(tables: Mapping[str, pd.DataFrame]) -> pd.DataFrame:
    """Every tick that has its LSL clock: ``trial_id``, ``tick``, ``t``,
    ``session_clock_s``, ordered by trial and tick."""
    s = tables["sample"]
    if "lsl_clock_s" not in s.columns:
        return pd.DataFrame(columns=["trial_id", "tick", "t", "session_clock_s"])
    out = s.loc[s["lsl_clock_s"].notna(), ["trial_id", "tick", "t", "lsl_clock_s"]]
    out = out.rename(columns={"lsl_clock_s": "session_clock_s"}).astype(
        {"trial_id": int, "tick": int, "t": float, "session_clock_s": float}
    )
    return out.sort_values(["trial_id", "tick"]).reset_index(drop=True)


def _offset_fits(tables: Mapping[str, pd.DataFrame]) -> pd.DataFrame:
    rows = []
    off = tables.get("lsl_offset", pd.DataFrame(columns=["stream_id", "segment"]))
    for (sid, seg), g in off.groupby(["stream_id", "segment"]):
        c, o = g["clock_s"].to_numpy(float), g["offset_s"].to_numpy(float)
        a, b = fit_offsets(c, o)
        resid = o - (a + b * c)
        rows.append(
            {
                "stream_id": int(sid),
                "segment": int(seg),
                "a": a,
                "b": b,
                "n": len(g),
                "spread_ms": float(np.ptp(o)) * 1e3,
                "resid_ms": float(np.max(np.abs(resid))) * 1e3,
            }
        )
    return pd.DataFrame(
        rows, columns=["stream_id", "segment", "a", "b", "n", "spread_ms", "resid_ms"]
    )


def to_trials(
    clock: np.ndarray,
    ticks: pd.DataFrame,
    trial_ids: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The trial (-1: none) and trial time [s] of each session-clock time ``clock`` [s]:
    a trial spans from one tick before its first tick's clock to its last tick's clock."""
    trial = np.full(len(clock), -1, dtype=int)
    t = np.full(len(clock), np.nan)
    for tid, g in ticks.groupby("trial_id"):
        if trial_ids is not None and tid not in trial_ids:
            continue
        c, tt = g["session_clock_s"].to_numpy(float), g["t"].to_numpy(float)
        inside = (clock >= c[0] - TRIAL_MARGIN_S) & (clock <= c[-1])
        trial[inside] = int(tid)
        t[inside] = clock_to_trial_time(clock[inside], c, tt)
    return trial, t


def clock_to_trial_time(
    clock: np.ndarray, tick_clock: np.ndarray, tick_t: np.ndarray
) -> np.ndarray:  # noqa: E501
    """Trial time [s] of session-clock times: linear between ticks, slope 1 outside."""
    out = np.interp(clock, tick_clock, tick_t)
    out = np.where(clock < tick_clock[0], tick_t[0] + (clock - tick_clock[0]), out)
    return np.where(clock > tick_clock[-1], tick_t[-1] + (clock - tick_clock[-1]), out)


def trial_time_to_clock(t: np.ndarray, tick_t: np.ndarray, tick_clock: np.ndarray) -> np.ndarray:
    """Session-clock time [s] of trial times: the inverse of :func:`clock_to_trial_time`."""
    return clock_to_trial_time(t, tick_t, tick_clock)


def stream_frame(
    tables: Mapping[str, pd.DataFrame], stream: pd.Series, fits: pd.DataFrame, ticks: pd.DataFrame
) -> pd.DataFrame:
    """One stream's samples, decoded, on the session's clock and assigned to trials."""
    chunks = tables["lsl_chunk"]
    chunks = chunks[chunks["stream_id"] == stream["id"]].sort_values("id")
    labels = [c for c in str(stream["channels"]).split(",") if c] or [
        f"ch{i}" for i in range(int(stream["channel_count"]))
    ]
    n_ch = int(stream["channel_count"])
    ts = [timestamps(b) for b in chunks["timestamps"]]
    vals = [decode(b, str(stream["dtype"]), n_ch) for b in chunks["data"]]
    segs = [np.full(len(x), int(s)) for x, s in zip(ts, chunks["segment"], strict=True)]
    time = np.concatenate(ts) if ts else np.zeros(0)
    seg = np.concatenate(segs) if segs else np.zeros(0, dtype=int)
    values = np.concatenate(vals) if vals else np.zeros((0, n_ch))
    clock = time + float(stream.get("clock_shift_s", 0.0) or 0.0)
    mine = fits[fits["stream_id"] == stream["id"]]
    for _, f in mine.iterrows():
        at = seg == int(f["segment"])
        clock[at] += f["a"] + f["b"] * time[at]
    trials = tables["trial"]
    own = trials.loc[trials["session_id"] == stream["session_id"], "id"].to_numpy()
    trial, trial_t = to_trials(clock, ticks, own)
    frame = pd.DataFrame(
        {
            "segment": seg,
            "timestamp": time,
            "session_clock_s": clock,
            "trial_id": trial,
            "trial_t_s": trial_t,
        }
    )
    for i, label in enumerate(labels[:n_ch]):
        frame[label] = values[:, i]
    return frame


def events_on_clock(tables: Mapping[str, pd.DataFrame], ticks: pd.DataFrame) -> pd.DataFrame:
    """The events of trials with ticks, with their time on the session's clock."""
    ev = tables["event"]
    ev = ev[ev["trial_id"].isin(ticks["trial_id"].unique())].copy()
    clock = np.full(len(ev), np.nan)
    for tid, g in ticks.groupby("trial_id"):
        at = (ev["trial_id"] == tid).to_numpy()
        clock[at] = trial_time_to_clock(
            ev.loc[at, "t"].to_numpy(float),
            g["t"].to_numpy(float),
            g["session_clock_s"].to_numpy(float),
        )
    ev["session_clock_s"] = clock
    return ev.sort_values("session_clock_s", kind="stable").reset_index(drop=True)


def align(tables: Mapping[str, pd.DataFrame]) -> Aligned:
    """Every recorded or imported stream, the ticks and the events on the session's clock
    (``tables``: a study's raw tables, :func:`analysis.data.load_study`)."""
    ticks = tick_clocks(tables)
    fits = _offset_fits(tables)
    streams = {}
    for _, row in tables.get("lsl_stream", pd.DataFrame(columns=["id"])).iterrows():
        streams[int(row["id"])] = stream_frame(tables, row, fits, ticks)
    return Aligned(streams, ticks, events_on_clock(tables, ticks), fits)
