"""The report's figures (matplotlib, Agg, no pyplot state): PNG and SVG.

Thesis Figs. 7.50-7.52 (means and standard deviations per mode as bars, the secondary
metrics with the baseline), Fig. 7.44b (clearance distribution per mode), and what issue 7
adds: the NASA-TLX subscale profile per mode, every trial's path per mode, each metric by
position in the participant's order (a learning or fatigue effect shows there).
"""

from __future__ import annotations

import io
from pathlib import Path

import matplotlib
import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from analysis.data import BASELINE
from analysis.metrics import Metric
from questionnaires import nasa_tlx

COLOURS = ("#4C72B0", "#DD8452", "#55A868", "#C44E52", "#8172B3", "#937860", "#DA8BC3")
BASELINE_COLOUR = "#8C8C8C"
CLEARANCE_EDGES_M = np.round(np.arange(21) * 0.1, 10)  # 0..2 m; a 21st bin >= 2 m
MAX_PATH_POINTS = 600


def _colour(level: str, modes: tuple[str, ...]) -> str:
    if level == BASELINE:
        return BASELINE_COLOUR
    return COLOURS[modes.index(level) % len(COLOURS)] if level in modes else COLOURS[-1]


def _figure(width: float, height: float, **margins: float) -> Figure:
    # fixed margins: a layout engine (tight, constrained) is slower (docs/results.md)
    fig = Figure(figsize=(width, height), dpi=100)
    FigureCanvasAgg(fig)
    fig.subplots_adjust(**{"left": 0.09, "right": 0.98, "bottom": 0.2, "top": 0.9, **margins})
    return fig


def save(fig: Figure, folder: Path, stem: str) -> tuple[Path, Path, str]:
    """Write ``stem.png`` and ``stem.svg`` into ``folder``.

    Returns
    -------
    (png_path, svg_path, svg_text) : the SVG text starts at ``<svg`` (no XML prolog), ready
    to inline in HTML.
    """
    folder.mkdir(parents=True, exist_ok=True)
    png = folder / f"{stem}.png"
    svg = folder / f"{stem}.svg"
    fig.savefig(png, format="png", dpi=100)
    text = svg_text(fig)
    svg.write_text(text, encoding="utf-8")
    return png, svg, text[text.index("<svg") :]


def svg_text(fig: Figure) -> str:
    """The figure as an SVG document (its text as text: small, searchable; no date)."""
    buffer = io.StringIO()
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        fig.savefig(buffer, format="svg", metadata={"Date": None})
    return buffer.getvalue()


def metric_figure(long: pd.DataFrame, metric: Metric, modes: tuple[str, ...]) -> Figure:
    """(a) mean and SD per level as bars with each participant's value; (b) the metric by
    position in the order, one line per mode (means, with the per-trial values as dots).

    Parameters
    ----------
    long : :func:`analysis.metrics.long_frame` of the metric.
    metric : its table entry (label, name).
    modes : the study's modes (for colours).
    """
    fig = _figure(8.0, 3.2, wspace=0.3)
    ax, ax_pos = fig.subplots(1, 2, width_ratios=(1.1, 1.0))
    levels = list(dict.fromkeys(long["mode"]))
    x = np.arange(len(levels))
    stats = long.groupby("mode", sort=False)["value"].agg(["mean", "std"]).reindex(levels)
    mean, sd = stats["mean"].to_numpy(), stats["std"].fillna(0.0).to_numpy()
    # a metric that cannot be negative (counts, times, ratings) gets no whisker below 0
    low = np.minimum(sd, np.maximum(mean, 0.0)) if (long["value"].dropna() >= 0).all() else sd
    ax.bar(
        x,
        mean,
        yerr=np.vstack((low, sd)),
        color=[_colour(lv, modes) for lv in levels],
        alpha=0.8,
        capsize=5,
        edgecolor="black",
        linewidth=0.6,
    )
    rng = np.random.default_rng(0)  # fixed jitter of the dots: a drawing, not the data
    for i, lv in enumerate(levels):
        v = long.loc[long["mode"] == lv, "value"].dropna().to_numpy()
        ax.scatter(i + rng.uniform(-0.15, 0.15, len(v)), v, s=9, color="black", zorder=3)
    ax.set_xticks(x, levels, rotation=15)
    ax.set_ylabel(metric.label)
    ax.set_title(f"{metric.name}: mean and SD")
    ax.grid(axis="y", alpha=0.3)
    drive = long[long["position"] >= 0]
    for lv in [m for m in levels if m != BASELINE]:
        d = drive[drive["mode"] == lv]
        means = d.groupby("position")["value"].mean()
        ax_pos.plot(means.index + 1, means.to_numpy(), "-o", color=_colour(lv, modes), label=lv)
        ax_pos.scatter(d["position"] + 1, d["value"], s=7, color=_colour(lv, modes), alpha=0.4)
    positions = sorted(drive["position"].unique())
    ax_pos.set_xticks([p + 1 for p in positions])
    ax_pos.set_xlabel("position in the participant's order")
    ax_pos.set_ylabel(metric.label)
    ax_pos.set_title("by position")
    ax_pos.grid(alpha=0.3)
    if len(levels):
        ax_pos.legend(fontsize=7)
    return fig


def tlx_profile_figure(trials: pd.DataFrame, modes: tuple[str, ...]) -> Figure:
    """Mean NASA-TLX rating per subscale, grouped bars per mode with SD error bars."""
    fig = _figure(8.0, 3.4, left=0.08, bottom=0.18)
    ax = fig.subplots()
    ids = nasa_tlx.SUBSCALE_IDS
    width = 0.8 / max(len(modes), 1)
    x = np.arange(len(ids))
    for i, mode in enumerate(modes):
        d = trials[trials["mode"] == mode]
        mean = [d[f"tlx_{s}"].mean() for s in ids]
        sd = [d[f"tlx_{s}"].std() for s in ids]
        ax.bar(
            x + (i - (len(modes) - 1) / 2) * width,
            mean,
            width,
            yerr=np.nan_to_num(sd),
            color=_colour(mode, modes),
            label=mode,
            capsize=3,
            edgecolor="black",
            linewidth=0.5,
        )
    ax.set_xticks(x, [s.title for s in nasa_tlx.SUBSCALES], rotation=15)
    ax.set_ylabel("rating (0-100), mean and SD")
    ax.set_ylim(0, 110)
    ax.set_title("NASA-TLX subscale profile per mode")
    ax.legend(fontsize=8)
    ax.grid(axis="y", alpha=0.3)
    return fig


def clearance_counts(
    samples: pd.DataFrame, trials: pd.DataFrame, outcomes: dict[int, dict]
) -> pd.DataFrame:
    """Tick counts per clearance bin and mode.

    Returns
    -------
    pandas.DataFrame
        Index: the 21 bin lower edges [m] (the last bin is >= 2 m); one column per mode.
    """
    bins = np.append(CLEARANCE_EDGES_M, np.inf)
    by_mode: dict[str, np.ndarray] = {}
    with_samples = set(samples["trial_id"].astype(int)) if len(samples) else set()
    for mode, tid in zip(trials["mode"], trials["trial_id"].astype(int), strict=True):
        counts = by_mode.setdefault(mode, np.zeros(len(CLEARANCE_EDGES_M)))
        if tid in with_samples:
            c = samples.loc[samples["trial_id"] == tid, "min_clearance_m"].to_numpy(float)
            counts += np.histogram(np.clip(c, 0.0, None), bins=bins)[0]
        else:
            hist = (outcomes.get(tid) or {}).get("clearance_histogram")
            if hist is not None and len(hist) == len(CLEARANCE_EDGES_M):
                counts += np.asarray(hist, dtype=float)
    return pd.DataFrame(by_mode, index=pd.Index(CLEARANCE_EDGES_M, name="bin_low_m"))


def clearance_figure(
    counts: pd.DataFrame,
    modes: tuple[str, ...],
    *,
    xlabel: str = "clearance to the nearest obstacle [m] (last bin: >= 2 m)",
    title: str = "Clearance distribution per mode",
) -> Figure:
    """Share of ticks per 0.1 m clearance bin, one step line per mode (Fig. 7.44b)."""
    fig = _figure(8.0, 3.2, bottom=0.16)
    ax = fig.subplots()
    for mode in counts.columns:
        c = counts[mode].to_numpy(float)
        share = c / c.sum() if c.sum() > 0 else c
        edges = np.append(counts.index.to_numpy(float), 2.1)
        ax.stairs(share, edges, color=_colour(mode, modes), label=mode, linewidth=1.6)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("share of ticks")
    ax.set_title(title)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return fig


def read_map(yaml_path: str | Path) -> tuple[np.ndarray, tuple[float, float, float, float]]:
    """A ROS map_server map as saved by the session engine: (image, extent).

    Returns
    -------
    image : (rows, cols) uint8, row 0 the top of the map (0 occupied, 254 free).
    extent : (x_min, x_max, y_min, y_max) [m], for ``imshow(extent=...)``.

    Raises
    ------
    ValueError
        Naming the file, when it is not such a map (only 8-bit binary PGM images).
    """
    path = Path(yaml_path)
    fields: dict[str, str] = {}
    for line in path.read_text(encoding="utf-8").splitlines():
        key, sep, value = line.partition(":")
        if sep:
            fields[key.strip()] = value.strip()
    try:
        resolution = float(fields["resolution"])
        origin = [float(v) for v in fields["origin"].strip("[]").split(",")[:2]]
        data = (path.parent / fields["image"]).read_bytes()
        magic, cols, rows, maxval, pixels = data.split(maxsplit=4)
        cols, rows = int(cols), int(rows)
        if magic != b"P5" or int(maxval) != 255 or len(pixels) < rows * cols:
            raise ValueError("an 8-bit binary PGM (P5) image")
        image = np.frombuffer(pixels[: rows * cols], dtype=np.uint8).reshape(rows, cols)
    except (KeyError, ValueError, IndexError, OSError) as error:
        raise ValueError(f"{path}: not a map saved by the session engine ({error})") from error
    x0, y0 = origin
    return image, (x0, x0 + cols * resolution, y0, y0 + rows * resolution)


def _aspect(
    samples: pd.DataFrame,
    background: tuple[np.ndarray, tuple[float, float, float, float]] | None,
) -> float:
    """Height over width of the paths figure's drawn area: the map's extent, else the
    paths' (1 without either)."""
    if background is not None:
        x0, x1, y0, y1 = background[1]
    elif len(samples):
        x0, x1 = float(samples["x"].min()), float(samples["x"].max())
        y0, y1 = float(samples["y"].min()), float(samples["y"].max())
    else:
        return 1.0
    width, height = abs(x1 - x0), abs(y1 - y0)
    return height / width if width > 0 and height > 0 else 1.0


def paths_figure(
    samples: pd.DataFrame,
    trials: pd.DataFrame,
    modes: tuple[str, ...],
    background: tuple[np.ndarray, tuple[float, float, float, float]] | None = None,
) -> Figure:
    """Every counted trial's path (x, y) in one panel per mode, on the map ``background``
    (:func:`read_map`) when given; two panels a row, each 6 in wide, so a page shows the
    scene's detail; the start a green triangle, the end a red cross (a route back to its
    start ends where it began: the two stay apart by shape and colour)."""
    n = max(len(modes), 1)
    cols = min(n, 2)
    rows = int(np.ceil(n / cols))
    aspect = _aspect(samples, background)  # height / width of the drawn area
    panel_h = min(max(6.0 * aspect, 3.0), 8.0) + 0.9  # + title and axis labels
    fig = _figure(6.0 * cols, panel_h * rows, left=0.07, right=0.98, bottom=0.9 / (panel_h * rows),
                  top=1 - 0.4 / (panel_h * rows), wspace=0.15, hspace=0.9 / panel_h)  # fmt: skip
    axes = np.atleast_1d(fig.subplots(rows, cols, sharex=True, sharey=True)).ravel()
    for ax in axes[n:]:
        ax.set_visible(False)
    grouped = {int(k): g for k, g in samples.groupby("trial_id")} if len(samples) else {}
    for ax, mode in zip(axes, modes, strict=False):
        if background is not None:
            image, extent = background
            ax.imshow(image, cmap="gray", vmin=0, vmax=255, extent=extent, alpha=0.6,
                      interpolation="nearest")  # fmt: skip
        for tid in trials.loc[trials["mode"] == mode, "trial_id"].astype(int):
            g = grouped.get(tid)
            if g is None or g.empty:
                continue
            g = g.sort_values("tick")
            step = max(1, int(np.ceil(len(g) / MAX_PATH_POINTS)))
            x, y = g["x"].to_numpy()[::step], g["y"].to_numpy()[::step]
            ax.plot(x, y, color=_colour(mode, modes), alpha=0.45, linewidth=1.0)
            ax.plot(g["x"].iloc[0], g["y"].iloc[0], "^", color="#1a9641", markersize=8,
                    markeredgecolor="white", label="start")  # fmt: skip
            ax.plot(g["x"].iloc[-1], g["y"].iloc[-1], "X", color="#d7191c", markersize=8,
                    markeredgecolor="white", label="end")  # fmt: skip
        handles, labels = ax.get_legend_handles_labels()
        if handles:
            unique = dict(zip(labels, handles, strict=True))
            ax.legend(unique.values(), unique.keys(), fontsize=8, loc="best")
        ax.set_title(mode)
        ax.set_aspect("equal", adjustable="box")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.grid(alpha=0.3)
    return fig
