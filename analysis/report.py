"""The study report: ``report.html``, ``figures/``, ``tables/`` and ``results.json``.

Thesis Sec. 7.6.2: per metric a one-way repeated-measures ANOVA with the mode as factor
(the baseline a fourth level of the secondary-task metrics) and Fisher's LSD where the null
is rejected at the protocol's alpha; Figs. 7.44b and 7.50-7.52. :func:`build_report` reads a
study (:mod:`analysis.data`), analyses every metric of :mod:`analysis.metrics` with
:func:`analysis.stats.analyse`, draws the figures (:mod:`analysis.figures`) and renders
``templates/report.html.j2``. In-the-loop recognition, measured for the modes with task
recognition only, is described per mode and never tested (:mod:`analysis.recognition`).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import jinja2
import pandas as pd
from markupsafe import Markup

from analysis import crashes, data_quality, lab_streams
from analysis import figures as fig
from analysis.data import BASELINE, AnalysisConfig, Frames, StudyData, load_study, tidy
from analysis.methods import methods, methods_markdown
from analysis.metrics import BY_NAME, Metric, long_frame, ordered_metrics
from analysis.presentation import (
    GLOSSARY,
    descriptive_rows,
    experience_summary,
    pair_rows,
    synthetic_banner,
    table_one,
    without_constant_levels,
)
from analysis.r_script import analysis_r
from analysis.recognition import DECILE_LABELS, describe, html_rows, recognition_tables
from analysis.stats import POSTHOC, analyse
from analysis.tables import apa_anova, format_p


@dataclass(frozen=True, slots=True)
class ReportPaths:
    """What :func:`build_report` wrote.

    Attributes
    ----------
    html : the report.
    results_json : {metric -> analyse() object, "recognition" -> the object of
        :func:`analysis.recognition.describe`}.
    figures : every PNG and SVG file.
    tables : every CSV file.
    metrics : names of the analysed metrics, in report order.
    seconds : wall time of the build [s].
    """

    html: Path
    results_json: Path
    figures: tuple[Path, ...]
    tables: tuple[Path, ...]
    metrics: tuple[str, ...]
    seconds: float


@dataclass(frozen=True, slots=True)
class _Written:
    """The files written so far, in order (lists filled as the report is built)."""

    figures: list[Path]
    tables: list[Path]

    def csv(self, frame: pd.DataFrame, path: Path) -> None:
        frame.to_csv(path, index=False)
        self.tables.append(path)

    def figure(self, figure, folder: Path, stem: str) -> tuple[Path, Path, str]:
        png, svg, svg_text = fig.save(figure, folder, stem)
        self.figures.extend([png, svg])
        return png, svg, svg_text


def analysis_frame(long: pd.DataFrame) -> tuple[pd.DataFrame, str | None]:
    """``long`` with ``order`` = position in the participant's order from 1, and that
    column's name; None (no order effects) when a level is not a position (the baseline)."""
    if (long["position"] < 0).any():
        return long, None
    return long.assign(order=long["position"] + 1), "order"


def _analyse_metric(
    long: pd.DataFrame, cfg: AnalysisConfig, metric: str
) -> tuple[dict | None, str]:
    """(the analyse() object, "") or (None, why the metric cannot be analysed): the
    protocol's planned test and post-hoc family, order effects where positions apply."""
    if long.empty or long["value"].notna().sum() == 0:
        return None, "no data"
    frame, order = analysis_frame(long)
    try:
        result = analyse(
            frame,
            dv="value",
            within="mode",
            subject="participant",
            alpha=cfg.alpha,
            gate=cfg.gate,
            test=cfg.test_for(metric),
            posthoc=cfg.posthoc,
            posthoc_gate=cfg.posthoc_gate,
            order=order,
        )
    except ValueError as error:
        return None, str(error)
    return result, ""


def _sections(
    data: StudyData,
    frames: Frames,
    out: Path,
    progress: Callable[[str], None],
    written: _Written,
    only: tuple[str, ...] | None,
) -> tuple[list[dict], list[dict], dict, dict]:
    """Per metric the template's section, the metrics skipped (and why), the results,
    and the planned metrics' long frames (for Table 1)."""
    cfg = data.config
    sections, skipped, results, longs = [], [], {}, {}
    for metric in ordered_metrics(cfg.metrics):
        if metric.descriptive or (only is not None and metric.name not in only):
            continue
        long = long_frame(frames, metric, baseline=cfg.secondary_baseline_level)
        planned = metric.name in cfg.metrics
        if planned:
            longs[metric.name] = (metric, long)
        tested, constant = without_constant_levels(metric, long)
        result, reason = _analyse_metric(tested, cfg, metric.name)
        if result is None:
            skipped.append({"name": metric.name, "planned": planned, "reason": reason})
            continue
        if constant:
            result["warnings"] = [
                *result["warnings"],
                f"{', '.join(constant)} left out of the test: 0 by construction "
                "(described in Table 1)",
            ]
        progress(f"metric {metric.name}: {apa_anova(result, alpha=cfg.alpha)}")
        results[metric.name] = result
        sections.append(_section(metric, planned, long, result, frames, cfg, out, written))
    return sections, skipped, results, longs


def _section(
    metric: Metric,
    planned: bool,
    long: pd.DataFrame,
    result: dict,
    frames: Frames,
    cfg: AnalysisConfig,
    out: Path,
    written: _Written,
) -> dict:
    """One metric's section: its figure and CSV tables written, the template's values."""
    notes = list(result["warnings"])
    expected = list(frames.modes) + (
        [BASELINE] if metric.baseline and cfg.secondary_baseline_level else []
    )
    left_out = [lv for lv in expected if lv not in result["levels"] and lv not in metric.zero_in]
    if left_out:
        notes.append(f"levels without any value left out: {', '.join(left_out)}")
    figure = fig.metric_figure(long, metric, frames.modes)
    png, svg, svg_text = written.figure(figure, out / "figures", f"metric_{metric.name}")
    _write_metric_tables(metric.name, result, out / "tables", written)
    other = "lsd_pooled" if cfg.posthoc == "lsd_paired" else "lsd_paired"
    return {
        "metric": metric,
        "planned": planned,
        "result": result,
        "apa": apa_anova(result, alpha=cfg.alpha),
        "apa_all": result["apa"],
        "planned_test": result["planned"],
        "order_effects": result["order"],
        "svg": Markup(svg_text),
        "png_name": png.name,
        "svg_name": svg.name,
        "descriptives": descriptive_rows(result),
        "lead": cfg.posthoc,
        "lead_pairs": pair_rows(result["posthoc"][cfg.posthoc], cfg.alpha),
        "other": other,
        "other_pairs": pair_rows(result["posthoc"][other], cfg.alpha),
        "notes": notes,
        "sphericity": result["sphericity"],
        "gg": result["greenhouse_geisser"],
        "p_gate": format_p(result["p_gate"], alpha=cfg.alpha),
        "p_unc": format_p(result["anova"]["p_unc"], alpha=cfg.alpha),
        "mauchly_p": format_p(result["sphericity"]["p"], alpha=0.05),  # Mauchly's alpha
        "anova": result["anova"],
    }


def _write_metric_tables(name: str, result: dict, tables: Path, written: _Written) -> None:
    """``<metric>_descriptives.csv`` and, when post-hoc tests ran, ``<metric>_posthoc.csv``
    (every family that ran, column ``form``)."""
    desc = pd.DataFrame([{"level": k, **v} for k, v in result["descriptives"].items()])
    written.csv(desc, tables / f"{name}_descriptives.csv")
    forms = [f for f in POSTHOC if result["posthoc"][f]]
    if forms:
        ph = pd.concat(
            [pd.DataFrame(result["posthoc"][form]).assign(form=form) for form in forms],
            ignore_index=True,
        )
        written.csv(ph, tables / f"{name}_posthoc.csv")


def _summary_table(results: dict[str, dict], planned: tuple[str, ...]) -> pd.DataFrame:
    rows = []
    for name, r in results.items():
        a = r["anova"]
        rows.append(
            {
                "metric": name,
                "planned": name in planned,
                "n_subjects": r["n_subjects"],
                "levels": "|".join(r["levels"]),
                "F": a["F"],
                "df_effect": a["df_effect"],
                "df_error": a["df_error"],
                "p_unc": a["p_unc"],
                "mauchly_p": r["sphericity"]["p"],
                "gg_eps": r["greenhouse_geisser"]["eps"],
                "gg_p": r["greenhouse_geisser"]["p"],
                "p_gate": r["p_gate"],
                "significant": r["significant"],
                "np2": a["np2"],
                "ng2": a["ng2"],
                "apa": apa_anova(r),
            }
        )
    return pd.DataFrame(rows)


def _scene_map(data: StudyData, frames: Frames) -> tuple | None:
    """The occupancy map of the main trials' scenario, saved by the session engine beside
    the recordings (``<recordings>/maps/<scenario>.yaml``), or None: not an SQLite file,
    several scenarios, or no map saved."""
    source = Path(data.source)
    trials = data.tables.get("trial")
    if not source.is_file() or trials is None or trials.empty:
        return None
    main = trials[trials["id"].isin(frames.trials["trial_id"])]
    scenarios = set(main["scenario"])
    if len(scenarios) != 1:
        return None
    name = scenarios.pop()
    for rel in main["recording_path"]:
        if rel:
            yaml = (source.parent / rel).parents[1] / "maps" / f"{name}.yaml"
            if yaml.is_file():
                try:
                    return fig.read_map(yaml)
                except ValueError:
                    return None
    return None


def build_report(
    db: str | Path,
    out: str | Path,
    *,
    metrics: tuple[str, ...] | None = None,
    progress: Callable[[str], None] | None = None,
) -> ReportPaths:
    """Analyse a study and write the report folder.

    Parameters
    ----------
    db : a study database (SQLite path or SQLAlchemy URL) or an ``asa export`` CSV folder.
    out : the report folder (created); ``report.html``, ``results.json``, ``figures/``
        (PNG and SVG) and ``tables/`` (CSV) are written into it, replacing earlier files
        of the same names.
    metrics : only these metrics (names of :data:`analysis.metrics.METRICS`); default all.
        Unknown names raise ``ValueError``.
    progress : called with one line per step (the CLI prints them on stderr).

    Returns
    -------
    ReportPaths

    Raises
    ------
    FileNotFoundError
        No such database or folder.
    ValueError
        Naming the source: not an asa-study database or export, or no completed main trial.
    """
    start = time.perf_counter()
    say = progress or (lambda _line: None)
    metrics = _checked_metrics(metrics)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out}: out must be a folder, and this is a file")
    data = load_study(db)  # bad input fails before any progress line: one line on stderr
    frames = tidy(data)
    say(
        f"read {db}: {len(frames.trials)} main trials of {frames.trials['participant'].nunique()} "
        f"participants, modes {', '.join(frames.modes)}"
    )
    (out / "tables").mkdir(parents=True, exist_ok=True)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    written = _Written(figures=[], tables=[])
    positions, orders = _write_frames(frames, out / "tables", written)
    sections, skipped, results, longs = _sections(data, frames, out, say, written, metrics)
    table1 = _write_table_one(frames, longs, out / "tables", written)
    recognition = _recognition(frames, out / "tables", say, written, metrics)
    if not results and not recognition:
        raise ValueError(
            f"{data.source}: no metric could be analysed "
            f"({'; '.join(s['name'] + ': ' + s['reason'] for s in skipped) or 'no data'})"
        )
    written.csv(_summary_table(results, data.config.metrics), out / "tables" / "summary.csv")
    _write_r_script(data, frames, results, out)
    say("figures: TLX profile, clearance, paths")
    extra = _extra_figures(data, frames, out, written)
    crash = _crashes(data, frames, out, written) if data.config.end_on_collision else None
    lab = _lab_streams(data, out, written)
    quality = data_quality.section(data.tables, written.csv, out)
    results_json = out / "results.json"
    stored = results if recognition is None else {**results, "recognition": recognition}
    results_json.write_text(json.dumps(stored, indent=1, allow_nan=False), encoding="utf-8")
    section = methods(data, frames)
    (out / "methods.md").write_text(methods_markdown(section), encoding="utf-8")
    html = _render_html(
        data, frames, positions, orders, sections, skipped, extra, recognition, section, crash,
        table1=table1, lab=lab, quality=quality,
    )  # fmt: skip
    html_path = out / "report.html"
    html_path.write_text(html, encoding="utf-8")
    say(f"wrote {html_path}")
    return ReportPaths(
        html=html_path,
        results_json=results_json,
        figures=tuple(written.figures),
        tables=tuple(written.tables),
        metrics=tuple(results),
        seconds=time.perf_counter() - start,
    )


def _write_table_one(frames: Frames, longs: dict, tables: Path, written: _Written) -> pd.DataFrame:
    """Table 1 of the planned metrics' long frames (the modes, then any further level such
    as the baseline), written as ``table1.csv``."""
    levels = list(frames.modes) + sorted(
        {lv for _, lg in longs.values() for lv in lg["mode"]} - set(frames.modes)
    )
    table1 = table_one(longs, levels)
    written.csv(table1, tables / "table1.csv")
    return table1


def _write_r_script(data: StudyData, frames: Frames, results: dict, out: Path) -> None:
    """``analysis.R``: the planned metrics' tests in R, beside ``tables/trials.csv``."""
    planned = [m for m in results if m in data.config.metrics]
    text = analysis_r(
        name=str(data.study["name"]),
        sha=str(data.study["protocol_sha256"]),
        alpha=data.config.alpha,
        metrics=planned,
        tests={m: results[m]["planned"]["test"] for m in planned},
        posthoc=data.config.posthoc,
        modes=list(frames.modes),
        gate=data.config.gate,
        posthoc_gate=data.config.posthoc_gate,
    )
    (out / "analysis.R").write_text(text, encoding="utf-8")


def _recognition(
    frames: Frames,
    tables: Path,
    say: Callable[[str], None],
    written: _Written,
    only: tuple[str, ...] | None,
) -> dict | None:
    """The recognition in the loop per mode (:func:`analysis.recognition.describe`), its
    three CSV tables written; None when the report is limited to metrics without it."""
    if only is not None and not any(BY_NAME[m].group == "recognition" for m in only):
        return None
    described = describe(frames)
    per_mode, per_task, per_decile = recognition_tables(described)
    written.csv(per_mode, tables / "recognition.csv")
    written.csv(per_task, tables / "recognition_per_task.csv")
    written.csv(per_decile, tables / "recognition_deciles.csv")
    for mode, d in described.items():
        say(
            f"recognition in the loop, {mode}: task match {d['loop_task_match']:.3f}, "
            f"task + target {d['loop_task_target_match']:.3f}, null {d['loop_null_rate']:.3f} "
            f"of {d['labelled_ticks']} labelled ticks"
        )
    return described


def _checked_metrics(metrics: tuple[str, ...] | None) -> tuple[str, ...] | None:
    if metrics is None:
        return None
    unknown = [m for m in metrics if m not in BY_NAME]
    if unknown:
        raise ValueError(f"metric {unknown[0]!r} is not known; allowed: {', '.join(BY_NAME)}")
    return tuple(metrics)


def _write_frames(
    frames: Frames, tables: Path, written: _Written
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The tidy frames and the counterbalancing table as CSV; (positions, orders) for the
    template."""
    written.csv(frames.trials, tables / "trials.csv")
    written.csv(frames.questions, tables / "questions.csv")
    written.csv(frames.responses, tables / "responses.csv")
    written.csv(frames.participants, tables / "participants.csv")
    written.csv(frames.aborted, tables / "aborted.csv")
    positions = pd.crosstab(frames.trials["mode"], frames.trials["position"] + 1)
    positions = positions.reindex(list(frames.modes))
    positions.columns = [f"position {c}" for c in positions.columns]
    written.csv(positions.reset_index(), tables / "counterbalancing.csv")
    orders = (
        frames.participants[frames.participants["main_trials"] > 0]
        .groupby(["order_index", "order"])
        .size()
        .rename("participants")
        .reset_index()
    )
    return positions, orders


def _extra_figures(data: StudyData, frames: Frames, out: Path, written: _Written) -> list[dict]:
    """The TLX profile, the clearance distribution (and its CSV) and the paths, where there
    are data; the template's entries."""
    figures = out / "figures"
    samples = data.tables["sample"]
    samples = samples[samples["trial_id"].isin(set(frames.trials["trial_id"]))]
    extra = []
    if frames.trials["tlx_raw"].notna().any():
        figure = fig.tlx_profile_figure(frames.trials, frames.modes)
        title = "NASA-TLX subscale profile per mode"
        extra.append(_extra(written, figure, figures, "tlx_profile", title))
    outcomes = dict(
        zip(data.tables["trial"]["id"].astype(int), data.tables["trial"]["outcome"], strict=True)
    )
    counts = fig.clearance_counts(samples, frames.trials, outcomes)
    if counts.to_numpy().sum() > 0:
        written.csv(counts.reset_index(), out / "tables" / "clearance_distribution.csv")
        figure = fig.clearance_figure(counts, frames.modes)
        title = "Clearance distribution per mode (thesis Fig. 7.44b)"
        extra.append(_extra(written, figure, figures, "clearance_distribution", title))
    if len(samples):
        background = _scene_map(data, frames)
        figure = fig.paths_figure(samples, frames.trials, frames.modes, background)
        title = "Every trial's path per mode (start o, end x)" + (
            "" if background is not None else "; no saved map to draw them on"
        )
        extra.append(_extra(written, figure, figures, "paths", title))
    return extra


def _crashes(data: StudyData, frames: Frames, out: Path, written: _Written) -> dict:
    """Sec. 7.5: Table 7.10 (CSV and rows) and the laser clearance distribution without the
    crashed trials (Fig. 7.44b); the template's ``crash`` entry."""
    trial_table = data.tables["trial"]
    table = crashes.table_7_10(frames.trials, trial_table)
    written.csv(table, out / "tables" / "clearance_table_7_10.csv")
    counts = crashes.distribution(frames.trials, trial_table, fig.CLEARANCE_EDGES_M)
    figure = None
    if counts.to_numpy().sum() > 0:
        written.csv(counts.reset_index(), out / "tables" / "lrf_clearance_distribution.csv")
        drawn = fig.clearance_figure(
            counts,
            frames.modes,
            xlabel="minimum laser range from the robot's centre [m] (last bin: >= 2 m)",
            title="Clearance distribution per mode, crashed trials left out",
        )
        title = "Clearance distribution per mode, all trials except the crashed ones (Fig. 7.44b)"
        figure = _extra(written, drawn, out / "figures", "lrf_clearance_distribution", title)
    crashed = table[table["crashed"]]
    return {
        "rows": crashes.html_rows(table, frames.modes),
        "note": crashes.CRASH_NOTE,
        "crashed": crashed[["participant", "mode"]].to_dict("records"),
        "figure": figure,
    }


def _lab_streams(data: StudyData, out: Path, written: _Written) -> dict | None:
    """The lab's streams per participant and trial (``tables/lab_streams.csv``) and one
    channel over a trial with its events (:mod:`analysis.lab_streams`); None without."""
    described = lab_streams.describe(data.tables)
    if described is None:
        return None
    table, drawn = described
    written.csv(table, out / "tables" / "lab_streams.csv")
    shown = table.astype(object).assign(
        rate_hz=[_cell(v, 1) for v in table["rate_hz"]],
        gap_s=[_cell(v, 3) for v in table["gap_s"]],
        offset_spread_ms=[_cell(v, 3) for v in table["offset_spread_ms"]],
    )
    figure = None
    if drawn is not None:
        figure = _extra(written, drawn[0], out / "figures", "lab_stream_channel", drawn[1])
    return {"rows": shown.to_dict("records"), "figure": figure}


def _cell(value: float, digits: int) -> str:
    return "" if pd.isna(value) else f"{value:.{digits}f}"


def _extra(written: _Written, figure, folder: Path, stem: str, title: str) -> dict:
    png, svg, text = written.figure(figure, folder, stem)
    return {"title": title, "svg": Markup(text), "png_name": png.name, "svg_name": svg.name}


def _render_html(
    data: StudyData,
    frames: Frames,
    positions: pd.DataFrame,
    orders: pd.DataFrame,
    sections: list[dict],
    skipped: list[dict],
    extra: list[dict],
    recognition: dict | None,
    section: dict,
    crash: dict | None = None,
    *,
    table1: pd.DataFrame,
    lab: dict | None = None,
    quality: dict | None = None,
) -> str:
    """``templates/report.html.j2`` rendered with the study's values."""
    counted = set(frames.trials["participant"])
    kinds = frames.participants[frames.participants["participant"].isin(counted)]["kind"]
    all_warnings = list(frames.warnings)
    for s in sections:
        all_warnings += [f"{s['metric'].name}: {w}" for w in s["notes"]]
    incomplete = frames.participants[
        (frames.participants["main_trials"] > 0) & ~frames.participants["complete"]
    ]
    timeouts = frames.trials[frames.trials["timed_out"]]
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(Path(__file__).parent / "templates"),
        autoescape=jinja2.select_autoescape(["html", "j2"]),
        undefined=jinja2.StrictUndefined,
    )
    return env.get_template("report.html.j2").render(
        study=data.study,
        source=data.source,
        config=data.config,
        n=len(counted),
        n_complete=int(frames.participants["complete"].sum()),
        kinds=kinds.value_counts().to_dict(),
        banner=synthetic_banner(kinds.value_counts().to_dict()),
        table1=table1.to_dict("records"),
        table1_levels=[c for c in table1.columns if c not in ("metric", "label", "n", "note")],
        glossary=GLOSSARY,
        design_caveat=next(
            (x["order_effects"]["caveat"] for x in sections if x["order_effects"]), ""
        ),
        experience=experience_summary(frames, counted),
        modes=frames.modes,
        positions=positions,
        orders=orders.to_dict("records"),
        sections=sections,
        skipped=skipped,
        extra=extra,
        recognition=None if recognition is None else html_rows(recognition),
        decile_labels=DECILE_LABELS,
        zip=zip,
        methods=section,
        crash=crash,
        lab=lab,
        quality=quality,
        warnings=all_warnings,
        aborted=frames.aborted.to_dict("records"),
        incomplete=incomplete.to_dict("records"),
        timeouts=timeouts[["participant", "mode", "position"]].to_dict("records"),
        timeout_policy=data.config.timeouts,
        timeout_counts=timeouts["mode"].value_counts(sort=False).to_dict(),
        n_trials=len(frames.trials),
        generated=time.strftime("%Y-%m-%d %H:%M:%S %Z"),
    )


__all__ = ["ReportPaths", "build_report"]
