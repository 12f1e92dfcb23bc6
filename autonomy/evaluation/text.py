"""The offline evaluation's result as tables for people (thesis Tables 7.6-7.9,
Fig. 7.25, Sec. 7.2.2)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from autonomy.evaluation.settings import CORRESPONDENCE, KIND_TIME, METHODS

# Table 7.9: (title, result key per pair, result key of the mean over pairs)
_PAIR_TABLES = (
    ("mean normalised entropy (Eq. 7.7)", "introspection_pairs", "introspection_entropy"),
    ("MICAD [standardised units] (Table 7.9)", "introspection_micad_pairs", "introspection_micad"),
)


def _num(value: float | None, fmt: str = "8.3f") -> str:
    """``value`` formatted, or a dash of the same width for a missing value."""
    width = int(fmt.split(".")[0])
    return "-".rjust(width) if value is None else format(value, fmt)


def _header(width: int, cell: int = 8, names: tuple[str, ...] = METHODS) -> str:
    return " " * width + "".join(f"{m:>{cell}}" for m in names)


def _f05_lines(result: Mapping[str, Any], labels: list[str], width: int) -> list[str]:
    lines = ["F0.5 (right task type and right target among all candidates; thesis Table 7.6)"]
    lines.append(_header(width))
    for c in [*labels, "macro"]:
        lines.append(f"{c:<{width}}" + "".join(f"{result['f05'][m][c]:8.3f}" for m in METHODS))
    for m in METHODS:
        conf = result["confusion"][m]
        lines += ["", f"confusion ({m}): rows true, columns predicted at the right target"]
        lines.append(" " * width + "".join(f"{c[:10]:>11}" for c in conf["columns"]))
        for name, row in zip(conf["rows"], conf["matrix"], strict=True):
            lines.append(f"{name:<{width}}" + "".join(f"{v:11d}" for v in row))
    return lines


def _correspondence_lines(result: Mapping[str, Any]) -> list[str]:
    """ACR and MICAD on held-out runs (Sec. 7.4.1, Tables 7.7-7.8)."""
    n_runs = len(result["correspondence_rates"][METHODS[0]])
    return [
        f"correspondence on {n_runs} held-out runs (Sec. 7.4.1, Tables 7.7-7.8)",
        "ACR: mean over runs of the share of test ticks whose most probable component",
        "(Eq. 5.8) is the target; MICAD: mean distance of the winning feature to the",
        "training points of its assigned task type [standardised units]; kind_time: the",
        "kind-and-time recogniser on the fold's SOGP, its most believed candidate, run",
        "tick by tick, and that candidate's best class",
        _header(8, 10, CORRESPONDENCE),
        "ACR     " + "".join(_num(result["acr"][m], "10.3f") for m in CORRESPONDENCE),
        "MICAD   " + "".join(_num(result["micad"][m], "10.3f") for m in CORRESPONDENCE),
    ]


def _introspection_lines(result: Mapping[str, Any]) -> list[str]:
    """Entropy and MICAD per training pair (Table 7.9) and the pooled histograms of
    the normalised entropy (Fig. 7.25), with the SOGP's rank."""
    pairs = list(result["introspection_pairs"][METHODS[0]])
    pw = max(len(p) for p in [*pairs, "mean"]) + 2
    lines = ["introspection on unseen task types (trained on a pair, tested on the rest)"]
    for title, per_pair, mean in _PAIR_TABLES:
        lines += ["", title, _header(pw)]
        for p in pairs:
            lines.append(f"{p:<{pw}}" + "".join(f"{result[per_pair][m][p]:8.3f}" for m in METHODS))
        lines.append(f"{'mean':<{pw}}" + "".join(f"{result[mean][m]:8.3f}" for m in METHODS))
    hist = result["introspection_histogram"]
    n = hist[METHODS[0]]["n"]
    lines += ["", f"normalised entropy histogram, {n} test points pooled over pairs (Fig. 7.25)"]
    lines.append(_header(10))
    edges = hist[METHODS[0]]["edges"]
    for b in range(len(edges) - 1):
        label = f"{edges[b]:.1f}-{edges[b + 1]:.1f}"
        lines.append(f"{label:<10}" + "".join(f"{hist[m]['counts'][b]:8d}" for m in METHODS))
    lines.append(f"{'median':<10}" + "".join(_num(hist[m]["median"]) for m in METHODS))
    lines.append(_rank_line(result["sogp_entropy_rank"]))
    return lines


def _kind_time_belief_lines(belief: Mapping[str, Any]) -> list[str]:
    """The kind-and-time recogniser's belief entropy on seen and unseen task types."""
    sides = [s for s in ("seen", "unseen") if belief.get(s)]
    seen = belief["seen"]["histogram"]
    lines = [
        "kind_time: normalised entropy (Eq. 7.7) of its belief over the tick's candidates",
        "and no task; seen: held-out runs of the task types it was trained on (test ticks);",
        "unseen: trained on a pair, along the other types' runs (their way points)",
        " " * 10 + "".join(f"{s:>10}" for s in sides),
    ]
    edges = seen["edges"]
    for b in range(len(edges) - 1):
        label = f"{edges[b]:.1f}-{edges[b + 1]:.1f}"
        counts = "".join(f"{belief[s]['histogram']['counts'][b]:10d}" for s in sides)
        lines.append(f"{label:<10}{counts}")
    for name, get in (
        ("points", lambda s: belief[s]["histogram"]["n"]),
        ("median", lambda s: belief[s]["histogram"]["median"]),
        ("mean", lambda s: belief[s]["entropy"]),
        ("no task", lambda s: belief[s]["no_task"]),
        ("decisive", lambda s: belief[s]["decisive"]),
    ):
        cells = "".join(
            f"{get(s):10d}" if name == "points" else _num(get(s), "10.3f") for s in sides
        )
        lines.append(f"{name:<10}{cells}")
    lines.append("no task: mean belief in no task (a sure 'no task' has a low entropy too);")
    lines.append("decisive: share of those ticks on which it would assist (beta > 0)")
    return lines


def _rank_line(rank: int | None, over: str = "") -> str:
    where = {1: " (highest)", len(METHODS): " (lowest)"}.get(rank or 0, "")
    return f"SOGP entropy rank: {rank} of {len(METHODS)}{where}, by mean normalised entropy{over}"


def _repeat_lines(rep: Mapping[str, Any], labels: list[str], width: int) -> list[str]:
    seeds = rep["seeds"]
    lines = [
        f"over {len(seeds)} seeds ({', '.join(map(str, seeds))}): mean +- sd; "
        "'sogp >=' is the share of seeds where the SOGP is at least every baseline",
        "F0.5",
        " " * width + "".join(f"{m:>14}" for m in METHODS) + f"{'sogp >=':>9}",
    ]
    for c in [*labels, "macro"]:
        cells = "".join(f"{rep['f05_mean'][m][c]:8.3f}+-{rep['f05_sd'][m][c]:.3f}" for m in METHODS)
        lines.append(f"{c:<{width}}{cells}{rep['sogp_at_least_baselines'][c]:9.2f}")
    lines.append(" " * width + "".join(f"{m:>14}" for m in CORRESPONDENCE))
    rows = [("ACR", "acr"), ("MICAD", "micad")]
    if rep["introspection_entropy_mean"]:
        rows += [
            ("entropy unseen", "introspection_entropy"),
            ("MICAD unseen", "introspection_micad"),
        ]
    for name, key in rows:
        mean, sd = rep[f"{key}_mean"], rep[f"{key}_sd"]
        cells = "".join(
            f"{mean[m]:8.3f}+-{sd[m]:.3f}" if m in mean else "-".rjust(14) for m in CORRESPONDENCE
        )
        lines.append(f"{name:<{width}}{cells}")
    if rep["sogp_entropy_rank"] is not None:
        lines.append(_rank_line(rep["sogp_entropy_rank"], " over the seeds"))
    mean, sd = rep["kind_time_entropy_mean"], rep["kind_time_entropy_sd"]
    belief = ", ".join(f"{s} {mean[s]:.3f}+-{sd[s]:.3f}" for s in mean)
    lines.append(f"{KIND_TIME} belief entropy (Eq. 7.7): {belief or '-'}")
    return lines


def format_report(result: Mapping[str, Any]) -> str:
    """Human-readable tables of :func:`autonomy.evaluation.evaluate`'s result (with its
    ``"repeats"`` summary, if any)."""
    labels = list(result["labels"])
    width = max(len(x) for x in [*labels, "macro", "entropy unseen"]) + 2
    lines = [
        f"{result['n_runs']} runs, {result['folds']}-fold cross-validation by run, seed "
        f"{result['seed']}; {result['n_test_ticks']} test ticks; model {result['model'] or '-'}",
        "",
        *_f05_lines(result, labels, width),
        "",
        *_correspondence_lines(result),
    ]
    if result["introspection_entropy"]:
        lines += ["", *_introspection_lines(result)]
    lines += ["", *_kind_time_belief_lines(result["kind_time_introspection"])]
    lines += ["", "trajectory rates on held-out runs (Sec. 7.2.2), mean over runs"]
    lines.append(f"{'':<14}{'success':>9}{'error':>9}{'null':>9}")
    for r, v in result["trajectory_rates"].items():
        lines.append(f"{r:<14}{v['success']:9.3f}{v['error']:9.3f}{v['null']:9.3f}")
    if result.get("repeats"):
        lines += ["", *_repeat_lines(result["repeats"], labels, width)]
    lines += ["", f"time: {result['timings_s']['total']:.1f} s"]
    return "\n".join(lines)
