"""The study report: ``report.html``, ``figures/``, ``tables/`` and ``results.json``.

Thesis Sec. 7.6.2: per metric a one-way repeated-measures ANOVA with the mode as factor
(the baseline a fourth level of the secondary-task metrics) and Fisher's LSD where the null
is rejected at the protocol's alpha; Figs. 7.44b and 7.50-7.52. :func:`build_report` reads a
study (:mod:`analysis.data`), analyses every metric of :mod:`analysis.metrics` with
:func:`analysis.stats.analyse` under the protocol's alpha and gate, draws the figures
(:mod:`analysis.figures`) and renders ``templates/report.html.j2``.

Decisions where the spec is silent
----------------------------------
- **One self-contained HTML file**: figures are inlined as SVG (text, scalable, searchable);
  the PNG and SVG files are written beside it in ``figures/`` for papers.
- **Which metrics**: all of the metric table with data, the protocol's planned metrics
  (``[analysis] metrics``) first and marked "planned"; a metric that cannot be analysed
  (no data, fewer than two complete participants or levels) is listed with the reason and
  left out of ``results.json``.
- **Post-hoc lead**: the protocol's ``posthoc`` form is the first table; the other LSD form
  follows, collapsed. Both are in ``results.json`` and ``tables/``.
- **Warnings** of every analysis (listwise deletion naming who was dropped, zero variance,
  singular covariance) are printed under that metric and gathered at the top of the
  report; data-quality notes list the main trials not counted (aborted, superseded),
  participants without a complete set of modes and trials that timed out.
- **results.json** is exactly {metric name -> the object of ``asa stats --json``} (the
  return value of ``analyse``), nothing else, so a reader can feed it to the same tools.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import jinja2
import pandas as pd
from markupsafe import Markup

from analysis import figures as fig
from analysis.data import BASELINE, Frames, StudyData, load_study, tidy
from analysis.metrics import BY_NAME, long_frame, ordered_metrics
from analysis.stats import analyse
from analysis.tables import apa_anova, format_p
from questionnaires import experience as experience_q


@dataclass(frozen=True, slots=True)
class ReportPaths:
    """What :func:`build_report` wrote.

    Attributes
    ----------
    html : the report.
    results_json : {metric -> analyse() object}.
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


def _fmt(value: float | None, digits: int = 2) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    return f"{value:.{digits}f}"


def _experience_summary(frames: Frames, counted: set[str]) -> dict | None:
    r = frames.responses
    r = r[(r["instrument"] == experience_q.INSTRUMENT_ID) & r["participant"].isin(counted)]
    if r.empty:
        return None
    summaries, invalid = [], 0
    for _, g in r.groupby("participant"):
        answers = {
            item: (text if isinstance(text, str) and text else value)
            for item, value, text in zip(g["item"], g["value"], g["text"], strict=True)
        }
        answers = {
            k: int(v) if isinstance(v, float) and v.is_integer() else v for k, v in answers.items()
        }
        try:
            summaries.append(experience_q.summarise(answers))
        except ValueError:
            invalid += 1
    if not summaries:
        return None
    ages = [s["age"] for s in summaries if s["age"] is not None]
    hands: dict[str, int] = {}
    for s in summaries:
        key = s["handedness"] or "not given"
        hands[key] = hands.get(key, 0) + 1
    return {
        "n": len(summaries),
        "invalid": invalid,
        "age": (
            f"{sum(ages) / len(ages):.1f} (range {min(ages)}-{max(ages)}, n = {len(ages)})"
            if ages
            else "not given"
        ),
        "handedness": ", ".join(f"{k} {v}" for k, v in sorted(hands.items())),
        "experienced": {
            d: sum(bool(s[f"experienced_{d}"]) for s in summaries)
            for d in experience_q.EXPERIENCE_DOMAINS
        },
        "any_experience": sum(bool(s["any_experience"]) for s in summaries),
        "experience_mean": sum(s["experience_mean"] for s in summaries) / len(summaries),
    }


def _pair_rows(pairs: list[dict]) -> list[dict]:
    return [
        {
            "pair": f"{p['a']} - {p['b']}",
            "diff": _fmt(p["diff"], 3),
            "t": _fmt(p["t"]),
            "df": _fmt(p["df"], 0) if float(p["df"]).is_integer() else _fmt(p["df"]),
            "p": format_p(p["p"]),
            "ci": f"[{_fmt(p['ci_low'], 3)}, {_fmt(p['ci_high'], 3)}]",
            "significant": p["significant"],
        }
        for p in pairs
    ]


def _descriptive_rows(result: dict) -> list[dict]:
    return [
        {
            "level": level,
            "mean": _fmt(d["mean"], 3),
            "sd": _fmt(d["sd"], 3),
            "se": _fmt(d["se"], 3),
            "n": d["n"],
        }
        for level, d in result["descriptives"].items()
    ]


def _write_csv(frame: pd.DataFrame, path: Path, written: list[Path]) -> None:
    frame.to_csv(path, index=False)
    written.append(path)


def _sections(
    data: StudyData,
    frames: Frames,
    out: Path,
    progress: Callable[[str], None],
    written_figs: list[Path],
    written_tables: list[Path],
    only: tuple[str, ...] | None,
) -> tuple[list[dict], list[dict], dict]:
    cfg = data.config
    sections, skipped, results = [], [], {}
    tables = out / "tables"
    figures = out / "figures"
    for metric in ordered_metrics(cfg.metrics):
        if only is not None and metric.name not in only:
            continue
        long = long_frame(frames, metric, baseline=cfg.secondary_baseline_level)
        planned = metric.name in cfg.metrics
        if long.empty or long["value"].notna().sum() == 0:
            skipped.append({"name": metric.name, "planned": planned, "reason": "no data"})
            continue
        try:
            result = analyse(
                long,
                dv="value",
                within="mode",
                subject="participant",
                alpha=cfg.alpha,
                gate=cfg.gate,
            )
        except ValueError as error:
            skipped.append({"name": metric.name, "planned": planned, "reason": str(error)})
            continue
        progress(f"metric {metric.name}: {apa_anova(result)}")
        results[metric.name] = result
        notes = list(result["warnings"])
        expected = list(frames.modes) + (
            [BASELINE] if metric.baseline and cfg.secondary_baseline_level else []
        )
        left_out = [lv for lv in expected if lv not in result["levels"]]
        if left_out:
            notes.append(f"levels without any value left out: {', '.join(left_out)}")
        figure = fig.metric_figure(long, metric, frames.modes)
        png, svg, svg_text = fig.save(figure, figures, f"metric_{metric.name}")
        written_figs += [png, svg]
        desc = pd.DataFrame([{"level": k, **v} for k, v in result["descriptives"].items()])
        _write_csv(desc, tables / f"{metric.name}_descriptives.csv", written_tables)
        if result["posthoc"]["ran"]:
            ph = pd.concat(
                [
                    pd.DataFrame(result["posthoc"][form]).assign(form=form)
                    for form in ("lsd_paired", "lsd_pooled")
                ],
                ignore_index=True,
            )
            _write_csv(ph, tables / f"{metric.name}_posthoc.csv", written_tables)
        other = "lsd_pooled" if cfg.posthoc == "lsd_paired" else "lsd_paired"
        sections.append(
            {
                "metric": metric,
                "planned": planned,
                "result": result,
                "apa": apa_anova(result),
                "svg": Markup(svg_text),
                "png_name": png.name,
                "svg_name": svg.name,
                "descriptives": _descriptive_rows(result),
                "lead": cfg.posthoc,
                "lead_pairs": _pair_rows(result["posthoc"][cfg.posthoc]),
                "other": other,
                "other_pairs": _pair_rows(result["posthoc"][other]),
                "notes": notes,
                "sphericity": result["sphericity"],
                "gg": result["greenhouse_geisser"],
                "p_gate": format_p(result["p_gate"]),
                "anova": result["anova"],
            }
        )
    return sections, skipped, results


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
    if metrics is not None:
        unknown = [m for m in metrics if m not in BY_NAME]
        if unknown:
            raise ValueError(f"metric {unknown[0]!r} is not known; allowed: {', '.join(BY_NAME)}")
        metrics = tuple(metrics)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out}: --out must be a folder, and this is a file")
    say(f"reading {db}")
    data = load_study(db)
    frames = tidy(data)
    cfg = data.config
    say(
        f"{len(frames.trials)} main trials of {frames.trials['participant'].nunique()} "
        f"participants, modes {', '.join(frames.modes)}"
    )
    (out / "tables").mkdir(parents=True, exist_ok=True)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    written_figs: list[Path] = []
    written_tables: list[Path] = []
    tables = out / "tables"
    _write_csv(frames.trials, tables / "trials.csv", written_tables)
    _write_csv(frames.questions, tables / "questions.csv", written_tables)
    _write_csv(frames.responses, tables / "responses.csv", written_tables)
    _write_csv(frames.participants, tables / "participants.csv", written_tables)
    _write_csv(frames.aborted, tables / "aborted.csv", written_tables)
    positions = pd.crosstab(frames.trials["mode"], frames.trials["position"] + 1)
    positions = positions.reindex(list(frames.modes))
    positions.columns = [f"position {c}" for c in positions.columns]
    _write_csv(positions.reset_index(), tables / "counterbalancing.csv", written_tables)
    orders = (
        frames.participants[frames.participants["main_trials"] > 0]
        .groupby(["order_index", "order"])
        .size()
        .rename("participants")
        .reset_index()
    )

    sections, skipped, results = _sections(
        data, frames, out, say, written_figs, written_tables, metrics
    )
    if not results:
        raise ValueError(
            f"{data.source}: no metric could be analysed "
            f"({'; '.join(s['name'] + ': ' + s['reason'] for s in skipped)})"
        )
    _write_csv(_summary_table(results, cfg.metrics), tables / "summary.csv", written_tables)

    extra = []
    say("figures: TLX profile, clearance, paths")
    counted_ids = set(frames.trials["trial_id"])
    samples = data.tables["sample"]
    samples = samples[samples["trial_id"].isin(counted_ids)]
    if frames.trials["tlx_raw"].notna().any():
        png, svg, text = fig.save(
            fig.tlx_profile_figure(frames.trials, frames.modes), out / "figures", "tlx_profile"
        )
        written_figs += [png, svg]
        extra.append(
            {
                "title": "NASA-TLX subscale profile per mode",
                "svg": Markup(text),
                "png_name": png.name,
                "svg_name": svg.name,
            }
        )
    outcomes = dict(
        zip(data.tables["trial"]["id"].astype(int), data.tables["trial"]["outcome"], strict=True)
    )
    counts = fig.clearance_counts(samples, frames.trials, outcomes)
    if counts.to_numpy().sum() > 0:
        _write_csv(counts.reset_index(), tables / "clearance_distribution.csv", written_tables)
        png, svg, text = fig.save(
            fig.clearance_figure(counts, frames.modes), out / "figures", "clearance_distribution"
        )
        written_figs += [png, svg]
        extra.append(
            {
                "title": "Clearance distribution per mode (thesis Fig. 7.44b)",
                "svg": Markup(text),
                "png_name": png.name,
                "svg_name": svg.name,
            }
        )
    if len(samples):
        background = _scene_map(data, frames)
        png, svg, text = fig.save(
            fig.paths_figure(samples, frames.trials, frames.modes, background),
            out / "figures",
            "paths",
        )
        written_figs += [png, svg]
        extra.append(
            {
                "title": "Every trial's path per mode (start o, end x)"
                + ("" if background is not None else "; no saved map to draw them on"),
                "svg": Markup(text),
                "png_name": png.name,
                "svg_name": svg.name,
            }
        )

    results_json = out / "results.json"
    results_json.write_text(json.dumps(results, indent=1, allow_nan=False), encoding="utf-8")

    counted = set(frames.trials["participant"])
    kinds = frames.participants[frames.participants["participant"].isin(counted)]["kind"]
    all_warnings = list(frames.warnings)
    for s in sections:
        all_warnings += [f"{s['metric'].name}: {w}" for w in s["notes"]]
    incomplete = frames.participants[
        (frames.participants["main_trials"] > 0) & ~frames.participants["complete"]
    ]
    timeouts = frames.trials[frames.trials["completed_task"].eq(False)]
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(Path(__file__).parent / "templates"),
        autoescape=jinja2.select_autoescape(["html", "j2"]),
        undefined=jinja2.StrictUndefined,
    )
    html = env.get_template("report.html.j2").render(
        study=data.study,
        source=data.source,
        config=cfg,
        n=len(counted),
        n_complete=int(frames.participants["complete"].sum()),
        kinds=kinds.value_counts().to_dict(),
        experience=_experience_summary(frames, counted),
        modes=frames.modes,
        positions=positions,
        orders=orders.to_dict("records"),
        sections=sections,
        skipped=skipped,
        extra=extra,
        warnings=all_warnings,
        aborted=frames.aborted.to_dict("records"),
        incomplete=incomplete.to_dict("records"),
        timeouts=timeouts[["participant", "mode", "position"]].to_dict("records"),
        n_trials=len(frames.trials),
        generated=time.strftime("%Y-%m-%d %H:%M:%S %Z"),
    )
    html_path = out / "report.html"
    html_path.write_text(html, encoding="utf-8")
    say(f"wrote {html_path}")
    return ReportPaths(
        html=html_path,
        results_json=results_json,
        figures=tuple(written_figs),
        tables=tuple(written_tables),
        metrics=tuple(results),
        seconds=time.perf_counter() - start,
    )


__all__ = ["ReportPaths", "build_report"]
