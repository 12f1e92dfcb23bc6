"""The report's data-quality section for browser participants (issue 37, DESIGN.md
"Participants in a browser"): per participant, how old the input was that drove each tick
[ticks of 50 ms] and the round trip of the state it answered [ms] (median, 95th percentile,
worst), the ticks driven on stale input (older than the protocol's ``[web] stale_ticks``,
4 by default) and the connections lost. Read from ``sample.input_age_ticks`` and
``sample.rtt_ms`` (revision 0005), which only a browser participant's ticks have.

Descriptive only: a participant with many stale ticks drove a laggier robot than the
others; whether to exclude them is the study's decision, made before the data are seen.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping

import numpy as np
import pandas as pd

COLUMNS = (
    "participant", "ticks", "age_median", "age_p95", "age_worst", "rtt_median_ms",
    "rtt_p95_ms", "rtt_worst_ms", "stale_ticks", "stale_share", "connections_lost",
)  # fmt: skip
DEFAULT_STALE_TICKS = 4  # study.web.settings.WebSettings.stale_ticks


def stale_ticks(protocol_text: str) -> int:
    """The protocol's ``[web] stale_ticks`` (its default where the protocol has none)."""
    try:
        web = tomllib.loads(protocol_text).get("web", {})
    except tomllib.TOMLDecodeError:
        return DEFAULT_STALE_TICKS
    value = web.get("stale_ticks", DEFAULT_STALE_TICKS) if isinstance(web, dict) else None
    return value if isinstance(value, int) and value >= 1 else DEFAULT_STALE_TICKS


def describe(tables: Mapping[str, pd.DataFrame]) -> pd.DataFrame | None:
    """One row per browser participant (:data:`COLUMNS`); None when no tick has timing."""
    sample = tables["sample"]
    if "input_age_ticks" not in sample or not sample["input_age_ticks"].notna().any():
        return None
    stale = stale_ticks(str(tables["study"]["protocol_text"].iloc[0]))
    trial = tables["trial"][["id", "participant_id"]].rename(columns={"id": "trial_id"})
    people = tables["participant"][["id", "code"]].rename(columns={"id": "participant_id"})
    timed = sample.loc[sample["input_age_ticks"].notna(), ["trial_id", "input_age_ticks", "rtt_ms"]]
    timed = timed.merge(trial, on="trial_id").merge(people, on="participant_id")
    lost = _connections_lost(tables, trial, people)
    rows = []
    for code, g in timed.groupby("code", sort=True):
        age = g["input_age_ticks"].to_numpy(dtype=float)
        rtt = g["rtt_ms"].dropna().to_numpy(dtype=float)
        q = lambda x, p: float(np.percentile(x, p)) if len(x) else np.nan  # noqa: E731
        rows.append({
            "participant": code, "ticks": len(g), "age_median": q(age, 50), "age_p95": q(age, 95),
            "age_worst": float(age.max()), "rtt_median_ms": q(rtt, 50), "rtt_p95_ms": q(rtt, 95),
            "rtt_worst_ms": float(rtt.max()) if len(rtt) else np.nan,
            "stale_ticks": int((age > stale).sum()), "stale_share": float((age > stale).mean()),
            "connections_lost": int(lost.get(code, 0)),
        })  # fmt: skip
    return pd.DataFrame(rows, columns=list(COLUMNS))


def _connections_lost(
    tables: Mapping[str, pd.DataFrame], trial: pd.DataFrame, people: pd.DataFrame
) -> dict[str, int]:
    event = tables["event"]
    lost = event.loc[event["kind"] == "connection_lost", ["trial_id"]].dropna()
    lost = (
        lost.astype({"trial_id": int})
        .merge(trial, on="trial_id")
        .merge(people, on="participant_id")
    )
    return lost.groupby("code").size().to_dict()


def section(tables: Mapping[str, pd.DataFrame], write_csv, folder) -> dict | None:
    """The template's values (rows as text) after ``write_csv(table, path)`` wrote
    ``tables/data_quality.csv`` into ``folder``; None without browser participants."""
    table = describe(tables)
    if table is None:
        return None
    write_csv(table, folder / "tables" / "data_quality.csv")
    shown = table.astype(object)
    for col in COLUMNS[2:8]:
        shown[col] = ["" if pd.isna(v) else f"{v:.1f}" for v in table[col]]
    shown["stale_share"] = [f"{100 * v:.1f} %" for v in table["stale_share"]]
    return {"rows": shown.to_dict("records"), "stale": stale_ticks(
        str(tables["study"]["protocol_text"].iloc[0]))}  # fmt: skip
