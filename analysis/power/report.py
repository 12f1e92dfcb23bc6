"""The power report of ``asa power`` (issue 22): ``power.html``, every metric's power curves
in one figure (``power_curves.png``/``.svg``) and one figure per metric
(``figures/power_<metric>.png``/``.svg``, inlined in the page).

Rendered from the result object of the power analysis (``power.json``, made with
:mod:`analysis.power.summary`): the power of each planned metric's omnibus test and of each
pair (thesis Sec. 7.6.2) per simulated sample size with Clopper-Pearson intervals, the
smallest N reaching the target power, the bank's effect sizes, the settings, and the
limits of a power computed from a population model. Nothing is computed here but text and
drawings; figures as :mod:`analysis.figures` draws them (matplotlib, Agg, no pyplot).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jinja2
import numpy as np
from markupsafe import Markup
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from analysis import figures as fig
from analysis.data import BASELINE
from analysis.methods import _GATES, _POSTHOC_WORDS, posthoc_gate_words
from analysis.power.resample import OMNIBUS
from analysis.power.summary import describe_n
from analysis.presentation import descriptive_rows
from analysis.stats.apa import _ci, _num, format_p

CURVES_STEM = "power_curves"
OMNIBUS_COLOUR = "black"
TARGET_STYLE = {"color": "#555555", "linestyle": "--", "linewidth": 1.1}


@dataclass(frozen=True, slots=True)
class PowerReportPaths:
    """What :func:`write_power_report` wrote.

    Attributes
    ----------
    html : ``power.html``, self-contained (inline CSS and SVG).
    curves_png, curves_svg : every metric's panel in one figure.
    figures : per metric its own figure, PNG then SVG, in the result's metric order.
    """

    html: Path
    curves_png: Path
    curves_svg: Path
    figures: tuple[Path, ...]


# ------------------------------------------------------------------------------- figures


def colours_by_test(metrics: Sequence[Mapping]) -> dict[str, str]:
    """Test name -> line colour, the same in every panel: the omnibus test black, each
    pair of levels a colour of :data:`analysis.figures.COLOURS` in order of appearance."""
    colours = {OMNIBUS: OMNIBUS_COLOUR}
    for m in metrics:
        for t in m["tests"]:
            if t["test"] not in colours:
                colours[t["test"]] = fig.COLOURS[(len(colours) - 1) % len(fig.COLOURS)]
    return colours


def _test_label(name: str) -> str:
    return "omnibus test" if name == OMNIBUS else name


def _line_style(name: str, colours: Mapping[str, str]) -> dict[str, Any]:
    """A test's line: the omnibus test thick (drawn below the pairs, so a pair as powerful
    shows on top of it), each pair thin."""
    omnibus = name == OMNIBUS
    return {
        "color": colours[name],
        "marker": "o",
        "linewidth": 3.0 if omnibus else 1.4,
        "markersize": 5.0 if omnibus else 3.5,
        "zorder": 2 if omnibus else 3,
    }


def _panel(ax: Axes, metric: Mapping, colours: Mapping[str, str], *, target: float) -> None:
    """One metric's power curves on ``ax``: a line per test through the simulated sizes,
    its pointwise CI as a band, the target power dashed."""
    sizes: list[int] = []
    for t in metric["tests"]:
        n = [p["n"] for p in t["curve"]]
        sizes = sorted(set(sizes) | set(n))
        power = [np.nan if p["power"] is None else p["power"] for p in t["curve"]]
        ax.fill_between(
            n,
            [p["ci_low"] for p in t["curve"]],
            [p["ci_high"] for p in t["curve"]],
            color=colours[t["test"]],
            alpha=0.12,
            linewidth=0,
        )
        ax.plot(n, power, **_line_style(t["test"], colours))
    ax.axhline(target, **TARGET_STYLE)
    if sizes:
        pad = max(0.04 * (sizes[-1] - sizes[0]), 0.5)
        ax.set_xlim(sizes[0] - pad, sizes[-1] + pad)
        ax.set_xticks(sizes)
    ax.set_ylim(-0.03, 1.03)
    ax.set_yticks(np.linspace(0.0, 1.0, 6))
    ax.set_xlabel("sample size N (participants)")
    ax.set_ylabel("power")
    ax.set_title(metric["label"], parse_math=False)  # a "$" in a label is no TeX
    ax.grid(alpha=0.3)


def _legend_handles(
    names: Sequence[str], colours: Mapping[str, str], *, target: float, ci_level: float
) -> list:
    """The shared legend: a line per test, the CI band, the target."""
    handles: list = [Line2D([], [], **_line_style(n, colours), label=_test_label(n)) for n in names]
    handles.append(Patch(color="#777777", alpha=0.25, label=f"{100 * ci_level:g} % CI"))
    handles.append(Line2D([], [], **TARGET_STYLE, label=f"target power {target:g}"))
    return handles


def curves_figure(
    metrics: Sequence[Mapping],
    colours: Mapping[str, str],
    *,
    target: float,
    ci_level: float,
) -> Figure:
    """Every metric's power curves, a panel each (two or three a row), one legend: in the
    grid's first empty place, else below the panels."""
    n = max(len(metrics), 1)
    cols = 1 if n == 1 else (2 if n <= 4 else 3)
    rows = math.ceil(n / cols)
    spare = rows * cols > len(metrics)
    ncol = min(4, 2 * cols)
    legend_h = 0.0 if spare else 0.15 + 0.2 * math.ceil((len(colours) + 2) / ncol)  # [in]
    width, height = 4.6 * cols, 3.3 * rows + legend_h
    figure = fig._figure(
        width,
        height,
        left=0.65 / width,
        right=0.98,
        bottom=(legend_h + 0.5) / height,
        top=1 - 0.35 / height,
        wspace=0.28,
        hspace=0.85 / (3.3 - 0.85),
    )
    axes = np.atleast_1d(figure.subplots(rows, cols, squeeze=False)).ravel()
    for ax, metric in zip(axes, metrics, strict=False):
        _panel(ax, metric, colours, target=target)
    for ax in axes[len(metrics) :]:
        ax.set_axis_off()
    handles = _legend_handles(list(colours), colours, target=target, ci_level=ci_level)
    if spare:
        axes[len(metrics)].legend(handles=handles, loc="center", fontsize=9, frameon=False)
    else:
        figure.legend(handles=handles, loc="lower center", ncol=ncol, fontsize=8, frameon=False)
    return figure


def metric_figure(
    metric: Mapping, colours: Mapping[str, str], *, target: float, ci_level: float
) -> Figure:
    """One metric's power curves alone, large, the legend to the right of the axes."""
    figure = fig._figure(9.0, 4.6, left=0.08, right=0.7, bottom=0.13, top=0.92)
    ax = figure.subplots()
    _panel(ax, metric, colours, target=target)
    names = [t["test"] for t in metric["tests"]]
    handles = _legend_handles(names, colours, target=target, ci_level=ci_level)
    ax.legend(
        handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=9, frameon=False
    )
    return figure


# ---------------------------------------------------------------------------------- text


def _and(items: Sequence[Any]) -> str:
    """``"a, b and c"``."""
    words = [str(i) for i in items]
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " and " + words[-1]


def _design_sentence(result: Mapping) -> str:
    """What was simulated: the bank and its participants' trials."""
    s, bank, p = result["settings"], result["bank"], result["protocol"]
    baseline = any(BASELINE in m["levels"] for m in result["metrics"])
    completed = bank["statuses"].get("completed", bank["entries"])
    done = "" if completed == s["bank"] else f" ({completed} of them completed)"
    return (
        f"A bank of B = {s['bank']} synthetic participants was drawn from the platform's "
        f"population model{done}; each drove one main trial in each of the protocol's "
        f"{len(p['modes'])} modes ({', '.join(p['modes'])})"
        + (" and answered the baseline questions" if baseline else "")
        + f", headless and without recordings ({bank['main_trials']} main trials, "
        f"{bank['timed_out_trials']} of them timed out)."
    )


def _resampling_sentence(result: Mapping) -> str:
    """How the studies were drawn from the bank."""
    s, p = result["settings"], result["protocol"]
    scheme = p["counterbalancing"]
    if p["cycle"]:
        orders = (
            f"counterbalanced as the protocol's {scheme} scheme assigns orders (a study's j-th "
            "participant drawn among the bank's participants who drove the order the scheme "
            f"gives the j-th participant; a complete cycle every {p['cycle']} participants)"
        )
    else:
        orders = (
            f"in orders of the protocol's {scheme} scheme (any bank participant fits any place)"
        )
    return (
        f"For each sample size N = {_and(s['sizes'])}, S = {s['studies']} studies of N "
        f"participants were drawn from the bank without replacement, {orders}."
    )


def _test_words(test: str, gate: str) -> str:
    """The planned omnibus test as the methods text names it."""
    anova = (
        "a one-way repeated-measures ANOVA (Mauchly's test, the Greenhouse\u2013Geisser "
        f"correction: {_GATES.get(gate, gate)})"
    )
    return {
        "rm_anova": anova,
        "friedman": "Friedman's test",
        "auto": "the test chosen per kind of metric (Friedman's test for counts with many ties "
        f"and single rating items, else {anova})",
    }.get(test, test)


def _analysis_sentence(result: Mapping) -> str:
    """The planned analysis each resampled study went through."""
    s = result["settings"]
    by_test: dict[str, list[str]] = {}
    for m in result["metrics"]:
        by_test.setdefault(s["tests"].get(m["metric"], "rm_anova"), []).append(m["metric"])
    tests = "; ".join(
        f"{_and(names)} by {_test_words(t, s['gate'])}" for t, names in by_test.items()
    )
    ranks = set(by_test) - {"rm_anova"}
    gate = s.get("posthoc_gate", "auto")
    friedman = (
        "; with Friedman's test, by Wilcoxon signed-rank tests with Holm's correction "
        + ("where it rejected" if gate == "omnibus" else "whatever it gave")
        if ranks
        else ""
    )
    baseline = any(BASELINE in m["levels"] for m in result["metrics"])
    lsd = s["posthoc"].startswith("lsd")
    gated = gate == "omnibus" or (gate == "auto" and lsd)
    why = (
        ", so no such pair rejects more often than its omnibus test"
        if gated
        else ", each pair on its own (posthoc_gate "
        f"{gate}: {posthoc_gate_words(s['posthoc'], gate)})"
    )
    return (
        f"Each study was analysed as the protocol plans, at \u03b1 = {s['alpha']:g}: {tests}"
        + ("; the baseline a further level of the secondary-task metrics" if baseline else "")
        + f". Pairs of levels were compared by {_POSTHOC_WORDS.get(s['posthoc'], s['posthoc'])}"
        + (" only where the omnibus test rejected" if gated else "")
        + (" (Fisher's LSD is protected by it, thesis Sec. 7.6.2)" if lsd and gated else "")
        + f"{friedman}{why}."
    )


def methods_paragraph(result: Mapping) -> str:
    """The methods text for a pre-registration: what was simulated, how studies were
    drawn and analysed, and how power and the N for the target were estimated."""
    s, p = result["settings"], result["protocol"]
    return " ".join(
        [
            f"Statistical power was estimated by simulation with asa-study "
            f"{result['platform_version']} for the protocol \u201c{p['title']}\u201d "
            f"({p['name']}, SHA-256 {p['sha256'][:12]}).",
            _design_sentence(result),
            _resampling_sentence(result),
            _analysis_sentence(result),
            f"The power of a test is the share of the S studies in which it rejected (a "
            f"study whose analysis could not run counted as not rejecting), with exact "
            f"Clopper\u2013Pearson {100 * s['ci_level']:g} % confidence intervals; the N at "
            f"which a test reaches the target power of {s['target_power']:g} was "
            "interpolated linearly between the simulated sizes and rounded up, its interval "
            "the same interpolation of the confidence bounds.",
            f"Random seed {s['seed']}.",
        ]
    )


def limitations(result: Mapping) -> list[str]:
    """The limits of these numbers, from the result: a model's power, Monte Carlo error
    only, no practice exclusions, the counterbalancing cycle, failed analyses."""
    s, p = result["settings"], result["protocol"]
    largest = max(s["sizes"])
    out = [
        f"This is the power of the population model, not of people: the bank's "
        f"{s['bank']} participants are synthetic, drawn from the platform's model of "
        "drivers (a model, not data: docs/decisions.md), so the effects it detects are the "
        "model's (section 4). Compare them with a pilot of people before relying on an N.",
        f"The confidence intervals are Monte Carlo error only (S = {s['studies']} studies "
        f"per N); they leave out the uncertainty of the bank's finite sample: another bank "
        f"of {s['bank']} would give other curves. The studies share the bank's "
        f"participants: at N = {largest} each study holds {largest / s['bank']:.0%} of it.",
        "The bank has no practice phase, hence no practice exclusions: if the protocol "
        "excludes participants who fail the practice, recruit more than the N given here.",
        _cycle_note(s["sizes"], p),
    ]
    return out + _failed_notes(result)


def _cycle_note(sizes: Sequence[int], protocol: Mapping) -> str:
    cycle = protocol["cycle"]
    if not cycle:
        return (
            f"The {protocol['counterbalancing']} scheme has no complete cycle; with few "
            "participants its orders need not be balanced."
        )
    off = [n for n in sizes if n % cycle]
    tail = (
        f" Of the simulated sizes, N = {_and(off)} {'is' if len(off) == 1 else 'are'} not."
        if off
        else " Every simulated size is a multiple."
    )
    return (
        f"N should be a multiple of the counterbalancing cycle ({cycle} participants for "
        f"{protocol['counterbalancing']}), so that every order is used equally often; round "
        f"an interpolated N up to the next multiple.{tail}"
    )


def _failed_notes(result: Mapping) -> list[str]:
    """A note per metric with studies whose analysis could not run."""
    notes = []
    studies = result["settings"]["studies"]
    for m in result["metrics"]:
        failed = {int(n): k for n, k in m["failed"].items() if k}
        if failed:
            where = ", ".join(f"{k} of {studies} at N = {n}" for n, k in sorted(failed.items()))
            notes.append(
                f"{m['metric']}: some studies could not be analysed (too few complete "
                f"participants: {where}); they count as not rejecting, so the power there "
                "is a lower bound."
            )
    return notes


def _power_text(point: Mapping | None) -> str:
    """``"0.83 [0.80, 0.85]"``; ``"n/a"`` for a size not simulated."""
    if point is None:
        return "n/a"
    return f"{_num(point['power'])} [{_num(point['ci_low'])}, {_num(point['ci_high'])}]"


def _in_cycles(n: int | None, cycle: int | None) -> int | None:
    """``n`` rounded up to complete counterbalancing cycles, None when it already is one
    (or there is no N or no cycle)."""
    if n is None or not cycle or n % cycle == 0:
        return None
    return cycle * math.ceil(n / cycle)


def summary_rows(result: Mapping) -> list[dict]:
    """The summary table: per metric its tests, each with the power at every simulated
    size and the N for the target power (``reached`` marks the cells to highlight)."""
    s = result["settings"]
    target = s["target_power"]
    rows = []
    for m in result["metrics"]:
        tests = []
        for t in m["tests"]:
            by_n = {p["n"]: p for p in t["curve"]}
            cells = [
                {
                    "text": _power_text(by_n.get(n)),
                    "reached": n in by_n and (by_n[n]["power"] or 0.0) >= target,
                }
                for n in s["sizes"]
            ]
            found = t["n_for_power"]
            tests.append(
                {
                    "name": _test_label(t["test"]),
                    "cells": cells,
                    "n": describe_n(found),
                    "reached": found["n"] is not None,
                    "cycles": _in_cycles(found["n"], result["protocol"]["cycle"]),
                }
            )
        rows.append({"metric": m["metric"], "label": m["label"], "tests": tests})
    return rows


def effect_sections(result: Mapping) -> list[dict]:
    """Per metric the bank's effect sizes as text: partial eta squared with its CI, the
    planned test's p in the whole bank, the descriptives and each pair's mean difference
    and Cohen's d_z with their CIs (at 1 - alpha, as the study report)."""
    level = 1.0 - result["settings"]["alpha"]
    out = []
    for m in result["metrics"]:
        e = m["effects"]
        section: dict[str, Any] = {"metric": m["metric"], "label": m["label"], "effects": None}
        if e is not None:
            np2 = e["np2"]
            section["effects"] = {
                "n": e["n"],
                "test": e["planned_test"],
                "p": format_p(e["p"]),
                "np2": _num(np2["value"], zero=False),
                "np2_ci": _ci(np2["ci_low"], np2["ci_high"], np2["ci_level"] or 0.9, zero=False),
                "descriptives": descriptive_rows(e),
                "pairs": [
                    {
                        "pair": f"{p['a']} \u2212 {p['b']}",
                        "n": p["n"],
                        "diff": f"{_num(p['diff'])} [{_num(p['ci_low'])}, {_num(p['ci_high'])}]",
                        "dz": f"{_num(p['dz'])} [{_num(p['dz_ci_low'])}, {_num(p['dz_ci_high'])}]",
                    }
                    for p in e["pairs"]
                ],
                "level": f"{100 * level:g}",
            }
        out.append(section)
    return out


def _value_text(key: str, value: Any) -> str:
    """A setting's value as the page shows it: lists joined, mappings as ``k: v``, times
    in seconds also in minutes or hours."""
    if isinstance(value, Mapping):
        return "; ".join(f"{k}: {_value_text(k, v)}" for k, v in value.items()) or "none"
    if isinstance(value, list | tuple):
        return "(" + ", ".join(_value_text(key, v) for v in value) + ")"
    if isinstance(value, bool) or value is None:
        return str(value)
    if isinstance(value, float):
        text = f"{value:,.0f}" if abs(value) >= 1000 else f"{value:.4g}"
        if not key.endswith("_s") or "_per_" in key:  # a rate (per_s, per_cpu_s): no unit
            return text
        if value < 120:
            return f"{text} s"
        return (
            f"{text} s ({value / 60:.1f} min)"
            if value < 7200
            else f"{text} s ({value / 3600:.2f} h)"
        )
    return str(value)


def settings_tables(result: Mapping) -> dict[str, list[tuple[str, str]]]:
    """(name, value text) rows of every entry of the settings, the bank (its population
    model apart), the population model's parameters, the protocol and the timing."""

    def rows(entries: Mapping) -> list[tuple[str, str]]:
        return [
            (k, "the parameters below" if k == "population" else _value_text(k, v))
            for k, v in entries.items()
        ]

    return {
        "protocol": rows(result["protocol"]),
        "settings": rows(result["settings"]),
        "bank": rows(result["bank"]),
        "population": rows(result["bank"].get("population") or {}),
        "timing": rows(result["timing"]),
    }


# -------------------------------------------------------------------------------- output


def write_power_report(result: dict, out: Path) -> PowerReportPaths:
    """Write the power report of ``result`` (the object of ``power.json``) into ``out``.

    Parameters
    ----------
    result : the power analysis's result (keys ``title``, ``protocol``, ``settings``,
        ``bank``, ``metrics``, ``summary``, ``timing``...; see :mod:`analysis.power`).
    out : the folder (created); ``power.html``, ``power_curves.png``/``.svg`` and
        ``figures/power_<metric>.png``/``.svg`` are written into it, replacing earlier
        files of the same names. ``power.json`` is not written here.

    Returns
    -------
    PowerReportPaths

    Raises
    ------
    ValueError
        ``out`` is a file.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out}: out must be a folder, and this is a file")
    out.mkdir(parents=True, exist_ok=True)
    s, metrics = result["settings"], result["metrics"]
    colours = colours_by_test(metrics)
    style = {"target": s["target_power"], "ci_level": s["ci_level"]}
    curves_png, curves_svg, _ = fig.save(curves_figure(metrics, colours, **style), out, CURVES_STEM)
    files: list[Path] = []
    panels = []
    for m in metrics:
        png, svg, text = fig.save(
            metric_figure(m, colours, **style), out / "figures", f"power_{m['metric']}"
        )
        files += [png, svg]
        panels.append(
            {
                "metric": m["metric"],
                "label": m["label"],
                "svg": Markup(text),
                "png": f"figures/{png.name}",
                "svg_file": f"figures/{svg.name}",
            }
        )
    html = out / "power.html"
    html.write_text(render_html(result, panels), encoding="utf-8")
    return PowerReportPaths(
        html=html, curves_png=curves_png, curves_svg=curves_svg, figures=tuple(files)
    )


def render_html(result: Mapping, panels: Sequence[Mapping]) -> str:
    """``templates/power.html.j2`` rendered with ``result`` and the inline figures."""
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(Path(__file__).parents[1] / "templates"),
        autoescape=jinja2.select_autoescape(["html", "j2"]),
        undefined=jinja2.StrictUndefined,
    )
    s = result["settings"]
    from_pilot = result.get("source") == "pilot"
    if from_pilot:  # asa power --from-study (issue 39)
        from analysis.power import pilot_text

        text = {
            "methods": pilot_text.pilot_methods(result),
            "tables": pilot_text.pilot_settings_tables(result),
            "limitations": pilot_text.pilot_limitations(result),
            "spread": pilot_text.spread_rows(result),
        }
    else:
        text = {
            "methods": methods_paragraph(result),
            "tables": settings_tables(result),
            "limitations": limitations(result),
            "spread": [],
        }
    return env.get_template("power.html.j2").render(
        result=result,
        from_pilot=from_pilot,
        protocol=result["protocol"],
        settings=s,
        summary=result["summary"],
        sizes=s["sizes"],
        rows=summary_rows(result),
        panels=panels,
        effects=[e for e in effect_sections(result) if "@" not in e["metric"]],
        **text,
        curves_png=f"{CURVES_STEM}.png",
        curves_svg=f"{CURVES_STEM}.svg",
    )


__all__ = [
    "PowerReportPaths",
    "curves_figure",
    "effect_sections",
    "limitations",
    "methods_paragraph",
    "metric_figure",
    "render_html",
    "settings_tables",
    "summary_rows",
    "colours_by_test",
    "write_power_report",
]
