"""The calibration report of ``asa calibrate`` (issue 39): ``<stem>.html`` beside the
population file, self-contained (inline CSS and SVG).

Rendered from the calibration's result object (``population.json``, made by
``study.jobs.calibrate.run``): the study and settings, a methods paragraph, each fitted
parameter with its interval against its search range and the base population's value, the
fit of every moment as a z value, and the limits of a calibration. Nothing is computed here
but text and drawings; figures as :mod:`analysis.figures` draws them (matplotlib, Agg).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import jinja2
import numpy as np
from markupsafe import Markup
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from analysis import figures as fig

Z_LIMIT = 6.0  # |z| beyond this is drawn at the edge, its value written beside it
RANGE_COLOUR, INTERVAL_COLOUR, BASE_COLOUR = "#D9D9D9", "#4C72B0", "#C44E52"
NEVER_FITTED = (
    "steering noise, caution, reaction delay and distraction style (with one trial per mode "
    "a study's few collisions cannot tell them apart), the NASA-TLX gain and noise "
    "(confounded with the bias's spread at one rating per mode) and the error rates"
)


def _finite(v: float | None) -> bool:
    return v is not None and math.isfinite(float(v))


def _num(v: float | None, digits: int = 3) -> str:
    """A value as the tables show it: ``digits`` decimals, 1 from 100 on; ``n/a`` for
    None/NaN."""
    if not _finite(v):
        return "n/a"
    return f"{v:,.{min(digits, 1)}f}" if abs(v) >= 100 else f"{v:.{digits}f}"


def _and(items: Sequence[Any]) -> str:
    words = [str(i) for i in items]
    if not words:
        return "none"
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " and " + words[-1]


def _level(result: Mapping) -> str:
    return f"{100 * result['settings']['level']:g} %"


# ------------------------------------------------------------------------------- figures


def parameter_figure(params: Sequence[Mapping], level: str) -> Figure:
    """One row per parameter on its search range (each row from its lower to its upper
    bound, written at the ends): the interval as a bar, the estimate a dot with its value,
    the base population's value a red tick."""
    n = max(len(params), 1)
    height = 0.6 * n + 1.1
    figure = fig._figure(8.0, height, left=0.27, right=0.98, bottom=0.45 / height,
                         top=1 - 0.35 / height)  # fmt: skip
    ax = figure.subplots()
    for i, p in enumerate(params):
        y = n - 1 - i
        lo, hi = p["search"]
        values = np.array([p["low"], p["high"], p["base"], p["estimate"]], dtype=float)
        low, high, base, estimate = np.clip((values - lo) / (hi - lo if hi > lo else 1.0), 0, 1)
        ax.hlines(y, 0.0, 1.0, color=RANGE_COLOUR, linewidth=9, zorder=1)
        ax.hlines(y, low, high, color=INTERVAL_COLOUR, linewidth=5, zorder=2)
        ax.plot(base, y, "|", color=BASE_COLOUR, markersize=18, mew=2.5, zorder=3)
        ax.plot(estimate, y, "o", color="black", markersize=6, zorder=4)
        ax.text(estimate, y + 0.22, f"{p['estimate']:.3g}", ha="center", fontsize=8,
                parse_math=False)  # fmt: skip
        for x, v, ha in ((-0.015, lo, "right"), (1.015, hi, "left")):
            ax.text(x, y, f"{v:.3g}", ha=ha, va="center", fontsize=8, color="#555555")
    labels = [p["name"] + (f" [{p['unit']}]" if p["unit"] else "") for p in reversed(params)]
    ax.set_yticks(range(n), labels or [""], parse_math=False)
    ax.set_ylim(-0.6, n - 0.4)
    ax.set_xlim(-0.14, 1.14)
    ax.set_xticks([])
    ax.set_xlabel("each parameter's search range, lower bound to upper bound")
    for side in ("top", "right", "left"):
        ax.spines[side].set_visible(False)
    handles = [
        Line2D([], [], color=RANGE_COLOUR, linewidth=8, label="search range"),
        Line2D([], [], color=INTERVAL_COLOUR, linewidth=5, label=f"{level} interval"),
        Line2D([], [], color="black", marker="o", linestyle="", label="estimate"),
        Line2D([], [], color=BASE_COLOUR, marker="|", markersize=12, mew=2.5, linestyle="",
               label="base population"),
    ]  # fmt: skip
    figure.legend(handles=handles, loc="upper center", ncol=4, fontsize=8, frameon=False)
    return figure


def _z_point(ax, y: float, z: float | None, colour: str, fitted: bool) -> None:
    """One moment's z: filled when fitted, hollow when not, an arrow at the edge beyond
    :data:`Z_LIMIT`, ``n/a`` where it is undefined."""
    if not _finite(z):
        ax.text(0.0, y, "n/a", ha="center", va="center", fontsize=7, color="#777777",
                bbox={"facecolor": "white", "edgecolor": "none", "pad": 0.5})  # fmt: skip
        return
    beyond = abs(z) > Z_LIMIT
    x = math.copysign(Z_LIMIT, z) if beyond else z
    marker = (">" if z > 0 else "<") if beyond else "o"
    ax.plot(x, y, marker, markersize=6, color=colour, mew=1.4,
            markerfacecolor=colour if fitted else "white")  # fmt: skip
    if beyond:
        ax.text(x - math.copysign(0.3, z), y, f"{z:+.1f}", ha="right" if z > 0 else "left",
                va="center", fontsize=7)  # fmt: skip


def moment_figure(moments: Sequence[Mapping]) -> Figure:
    """The z value (simulated - target) / SE of every moment, one row each, coloured by
    metric; fitted moments filled, the others hollow; guides at |z| = 1 and 2."""
    n = max(len(moments), 1)
    height = 0.2 * n + 1.3
    figure = fig._figure(8.0, height, left=0.42, right=0.97, bottom=0.55 / height,
                         top=1 - 0.35 / height)  # fmt: skip
    ax = figure.subplots()
    metrics = list(dict.fromkeys(m["metric"] for m in moments))
    colours = {m: fig.COLOURS[i % len(fig.COLOURS)] for i, m in enumerate(metrics)}
    for i, m in enumerate(moments):
        _z_point(ax, n - 1 - i, m["z"], colours[m["metric"]], bool(m["fitted"]))
    ax.axvline(0.0, color="black", linewidth=0.8)
    for g, style in ((1.0, ":"), (2.0, "--")):
        for s in (-g, g):
            ax.axvline(s, color="#777777", linestyle=style, linewidth=0.9)
    finite = [abs(m["z"]) for m in moments if _finite(m["z"])]
    lim = min(max([2.5, *(z + 0.5 for z in finite)]), Z_LIMIT + 0.5)
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-0.7, n - 0.3)
    ax.set_yticks(range(n), [m["moment"] for m in reversed(moments)] or [""], fontsize=7,
                  parse_math=False)  # fmt: skip
    ax.set_xlabel("z = (simulated \u2212 target) / SE")
    ax.grid(axis="y", alpha=0.2)
    handles = [
        Line2D([], [], marker="o", color="#555555", linestyle="", label="fitted"),
        Line2D([], [], marker="o", color="#555555", markerfacecolor="white", linestyle="",
               label="reported, not fitted"),
    ]  # fmt: skip
    figure.legend(handles=handles, loc="upper center", ncol=2, fontsize=8, frameon=False)
    return figure


# ---------------------------------------------------------------------------------- text


def _planned(result: Mapping) -> list[str]:
    """The planned metrics, in the moments' order."""
    return list(dict.fromkeys(m["metric"] for m in result["moments"]))


def _blocks_sentences(result: Mapping) -> str:
    """Which blocks were fitted (their parameters and the planned metrics that identify
    them) and which parameters keep the base population's values, and why."""
    planned, by = _planned(result), result.get("identified_by") or {}
    fitted = []
    for b in result["blocks"]:
        names = [p["name"] for p in result["parameters"] if p["block"] == b]
        which = [m for m in by.get(b, ()) if m in planned]
        by_text = f", identified by the planned {_and(which)}" if which else ""
        fitted.append(f"the {b} block ({_and(names)}{by_text})")
    words = [f"Fitted: {_and(fitted)}."]
    kept: dict[str, list[str]] = {}
    for p in result.get("not_fitted") or ():
        kept.setdefault(p["block"], []).append(p["name"])
    if kept:
        parts = [
            f"the {b} block's {_and(names)} (identified only by {_and(by.get(b, ('?',)))}"
            + (" with its baseline level" if b == "answer" else "") + ", which this study lacks)"
            for b, names in kept.items()
        ]  # fmt: skip
        words.append(f"Kept at the base population's values: {_and(parts)}.")
    elif not by:
        words.append("Every other parameter keeps the base population's value.")
    words.append(f"Never fitted, and kept at the base population's values: {NEVER_FITTED}.")
    return " ".join(words)


def methods_paragraph(result: Mapping) -> str:
    """The methods text a researcher can paste: the bank, the moments, the objective and
    its weighting, the optimiser, the blocks, the bootstrap and the intervals."""
    st, s = result["study"], result["settings"]
    planned, moments = _planned(result), result["moments"]
    se_draws = s.get("se_draws")
    draws = f"{se_draws} bootstraps" if se_draws else "a bootstrap"
    return " ".join([
        f"The synthetic population of asa-study {result['platform_version']} was calibrated "
        f"to the {st['participants']} participants of the study \u201c{st['name']}\u201d "
        f"(protocol SHA-256 {str(st['protocol_sha256'])[:12]}) by the method of simulated "
        "moments on one importance-weighted bank.",
        f"A bank of B = {s['bank']} synthetic participants drove the study's protocol once "
        "(one main trial per mode), the person-level values of the fitted blocks drawn from "
        "a wide proposal and every other value from the base population; a candidate "
        "population weighs the bank's entries by the ratio of its density to the "
        "proposal's, so no candidate needs a new simulation.",
        f"The moments are, for each planned metric ({_and(planned)}), each level's mean and "
        "standard deviation and the correlation of every pair of levels over the "
        f"participants with every level ({len(moments)} moments, "
        f"{sum(bool(m['fitted']) for m in moments)} of them fitted).",
        "The objective, the sum over the fitted moments of the squared difference between "
        "the weighted bank's moment and the study's divided by the study moment's standard "
        f"error ({draws} of the participants; a diagonal weighting), was minimised by "
        "Nelder\u2013Mead within each parameter's search range.",
        _blocks_sentences(result),
        f"R = {s['replicates']} bootstrap replicates redrew the study's participants and "
        f"the bank's entries and refitted; each {_level(result)} interval is the estimate "
        "\u00b1 z times the bootstrap standard deviation, cut to the search range.",
        f"Random seed {s['seed']}.",
    ])  # fmt: skip


def _at_bound(p: Mapping) -> list[str]:
    lo, hi = p["search"]
    return [w for w, hit in (("lower", p["low"] <= lo), ("upper", p["high"] >= hi)) if hit]


def limitations(result: Mapping) -> list[str]:
    """What a calibration does not give, from the result: moments only, unfitted metrics,
    intervals cut at a bound, a small effective bank."""
    planned = _planned(result)
    unfitted = [m for m in planned if not any(x["fitted"] for x in result["moments"]
                                              if x["metric"] == m)]  # fmt: skip
    cut = [f"{p['name']} ({' and '.join(_at_bound(p))})" for p in result["parameters"]
           if _at_bound(p)]  # fmt: skip
    ess = [m["bank_ess"] for m in result["moments"] if m["bank_ess"] is not None]
    return [
        "A calibration fits the means, spreads and correlations across levels of the planned "
        f"metrics only ({_and(planned)}): not other metrics, the shape of their "
        "distributions, nor order or learning effects. A synthetic study with the calibrated "
        "population should be compared with the study before it stands in for people.",
        "Metrics that no fitted block drives are reported, not fitted"
        + (f" (here: {_and(unfitted)})" if unfitted else " (none here)")
        + ", as are moments whose standard error is 0 or undefined. Collisions also depend "
        "on steering noise, caution and reaction delay, which are never fitted: how well "
        "they match rests on the base population's values of those.",
        "Each interval is cut at its parameter's search range, so an interval reaching a "
        "bound is truncated and its coverage unknown"
        + (f": here {_and(cut)}." if cut else "; none reaches one here."),
        "The simulated moments come from one bank reweighted: where a metric's effective "
        f"bank size is small (smallest here {_num(min(ess), 0) if ess else 'n/a'} of "
        f"{result['settings']['bank']}) they are noisy; the bootstrap redraws the bank, so "
        "the intervals carry this, but the estimates may be biased.",
    ]


def _far(m: Mapping) -> bool:
    """A fitted moment more than 2 SE off (highlighted)."""
    return bool(m["fitted"]) and _finite(m["z"]) and abs(m["z"]) > 2


def _seconds(v: float) -> str:
    return f"{v:.0f} s" if v < 120 else f"{v:.0f} s ({v / 60:.1f} min)"


def settings_rows(result: Mapping) -> list[tuple[str, str]]:
    """(name, value) of the study, the run's settings, the version and the timing."""
    st, s = result["study"], result["settings"]
    rows = [("study file", st["file"]), ("study name", st["name"]),
            ("protocol SHA-256", st["protocol_sha256"]), ("participants", st["participants"]),
            *s.items(), ("platform version", result["platform_version"]),
            ("created", result.get("created_at", "n/a"))]  # fmt: skip
    rows += [(k, _seconds(v)) for k, v in result["timing"].items()]
    return [(str(k), str(v)) for k, v in rows]


# -------------------------------------------------------------------------------- output


def render_html(result: Mapping, svgs: Mapping[str, str]) -> str:
    """``templates/calibration.html.j2`` rendered with ``result`` and the inline figures
    (``svgs``: ``parameters`` and ``moments``, SVG text)."""
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(Path(__file__).parent / "templates"),
        autoescape=jinja2.select_autoescape(["html", "j2"]),
        undefined=jinja2.StrictUndefined,
    )
    env.filters.update(
        num=_num,
        z=lambda z: f"{z:+.2f}" if _finite(z) else "n/a",
        cut=lambda p: " and ".join(_at_bound(p)),
    )
    env.tests["far"] = _far
    return env.get_template("calibration.html.j2").render(
        result=result,
        level=_level(result),
        methods=methods_paragraph(result),
        settings=settings_rows(result),
        limitations=limitations(result),
        figures={k: Markup(v) for k, v in svgs.items()},
    )


def _svg(figure: Figure) -> str:
    text = fig.svg_text(figure)
    return text[text.index("<svg") :]


def write_calibration_report(result: dict, out: Path) -> Path:
    """Write the calibration report of ``result`` (the object of ``population.json``)
    beside the population file ``out``: ``<stem>.html``, replacing an earlier one.

    Returns
    -------
    Path : the page written.
    """
    out = Path(out)
    svgs = {
        "parameters": _svg(parameter_figure(result["parameters"], _level(result))),
        "moments": _svg(moment_figure(result["moments"])),
    }
    html = out.with_suffix(".html")
    html.write_text(render_html(result, svgs), encoding="utf-8")
    return html
