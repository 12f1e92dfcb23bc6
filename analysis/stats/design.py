"""The one-way within-subject design: long frame -> complete-case wide table, descriptives.

Thesis Sec. 7.6.2 (one score per participant and mode).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd


@dataclass(frozen=True, slots=True)
class RepeatedMeasures:
    """The complete-case wide table of a one-way within-subject design.

    Attributes
    ----------
    y : np.ndarray
        (n, k) dependent variable, one row per complete subject, one column per level, in the
        dv's own unit.
    levels : tuple of str
        (k,) level labels in order of first appearance.
    subjects : tuple of str
        (n,) complete subjects in order of first appearance.
    dropped_subjects : tuple of str
        Subjects removed because they lack a value for some level.
    warnings : tuple of str
        Human-readable notes on what was dropped or averaged.
    """

    y: np.ndarray  # (n, k) [dv unit]
    levels: tuple[str, ...]
    subjects: tuple[str, ...]
    dropped_subjects: tuple[str, ...]
    warnings: tuple[str, ...]


def _labels(column: pd.Series, name: str) -> pd.Series:
    """Labels of an id column as strings; empty cells and string collisions are errors."""
    missing = column.isna()
    if missing.any():
        row = column.index[np.flatnonzero(missing.to_numpy())[0]]
        raise ValueError(f"column {name!r}: row {row} is empty; every row needs a {name}")
    if all(type(v) is str for v in column.to_numpy()):
        return column.astype(object)  # labels already: none can read as another
    as_text = column.map(str)
    originals = pd.DataFrame({"text": as_text, "value": column.map(repr)}).drop_duplicates()
    clash = originals["text"].duplicated(keep=False)
    if clash.any():
        values = ", ".join(originals.loc[clash, "value"].head(4))
        raise ValueError(
            f"column {name!r}: values {values} read as the same label; make the labels distinct"
        )
    return as_text


def _numeric_dv(column: pd.Series, name: str) -> np.ndarray:
    """The dv as float64; NaN means a missing cell, anything else non-numeric is an error."""
    if pd.api.types.is_bool_dtype(column):
        values = column.astype(float)
    else:
        values = pd.to_numeric(column, errors="coerce")
    bad = values.isna() & column.notna()
    if bad.any():
        row = column.index[np.flatnonzero(bad.to_numpy())[0]]
        raise ValueError(
            f"column {name!r}: row {row}: {column.loc[row]!r} is not a number "
            f"(the dependent variable must be numeric; leave a cell empty if it is missing)"
        )
    out = values.to_numpy(dtype=float)
    infinite = np.isinf(out)
    if infinite.any():
        row = column.index[np.flatnonzero(infinite)[0]]
        raise ValueError(f"column {name!r}: row {row}: {column.loc[row]!r} is not finite")
    return out


def _quoted(labels: list[str] | tuple[str, ...]) -> str:
    return ", ".join(repr(label) for label in labels)


def _check_columns(df: pd.DataFrame, *, dv: str, within: str, subject: str) -> None:
    """The three columns exist and differ; ``df`` is a DataFrame."""
    if not isinstance(df, pd.DataFrame):
        raise TypeError(f"expected a pandas DataFrame, got {type(df).__name__}")
    names = {"dv": dv, "within": within, "subject": subject}
    available = ", ".join(repr(str(c)) for c in df.columns) or "none"
    for role, column in names.items():
        if column not in df.columns:
            raise ValueError(
                f"column {column!r} ({role}) not found; available columns: {available}"
            )
    if len(set(names.values())) < 3:
        raise ValueError(
            f"dv, within and subject must be three different columns, got {dv!r}, {within!r}, "
            f"{subject!r}"
        )


def _levels(long: pd.DataFrame, within: str) -> tuple[str, ...]:
    """The level labels in order of first appearance; at least two."""
    levels = tuple(pd.unique(long["level"]))
    if len(levels) < 2:
        found = _quoted(levels) if levels else "none"
        raise ValueError(
            f"column {within!r}: only {len(levels)} level ({found}); a repeated-measures "
            f"ANOVA needs at least two"
        )
    return levels


def _repeated_cells_note(long: pd.DataFrame) -> list[str]:
    """The warning about (subject, level) cells of several rows, if any."""
    rows_per_cell = long.groupby(["subject", "level"], sort=False).size()
    repeated = rows_per_cell[rows_per_cell > 1]
    if not len(repeated):
        return []
    (who, where), count = next(iter(repeated.items()))
    return [
        f"{len(repeated)} (subject, level) cell(s) had more than one row; each was "
        f"replaced by the mean of its rows (e.g. subject {who!r}, level {where!r}: "
        f"{int(count)} rows)"
    ]


def _wide(
    long: pd.DataFrame, subjects: tuple, levels: tuple[str, ...]
) -> tuple[pd.DataFrame, list[str]]:
    """The (subject, level) table of cell means, subjects and levels in first-appearance
    order, and the note about cells of several rows (if any)."""
    s_codes = pd.Index(subjects).get_indexer(long["subject"])
    l_codes = pd.Index(levels).get_indexer(long["level"])
    cells = s_codes * len(levels) + l_codes
    if len(np.unique(cells)) == len(cells):  # one row per cell: no means to take
        y = np.full(len(subjects) * len(levels), np.nan)
        y[cells] = long["y"].to_numpy(dtype=float)
        table = y.reshape(len(subjects), len(levels))
        return pd.DataFrame(table, index=list(subjects), columns=list(levels)), []
    cell_means = long.groupby(["subject", "level"], sort=False)["y"].mean()
    wide = cell_means.unstack("level").reindex(index=list(subjects), columns=list(levels))
    return wide, _repeated_cells_note(long)


def _incomplete(wide: pd.DataFrame, levels: tuple[str, ...]) -> tuple[np.ndarray, tuple, list]:
    """(mask of incomplete subjects, their labels, the listwise-deletion warning if any)."""
    incomplete = wide.isna().any(axis=1)
    dropped = tuple(str(s) for s in wide.index[incomplete.to_numpy()])
    if not dropped:
        return incomplete.to_numpy(), dropped, []
    details = []
    for who in dropped:
        lacking = [str(level) for level in levels if pd.isna(wide.loc[who, level])]
        details.append(f"{who!r} (no {_quoted(lacking)})")
    note = (
        f"listwise deletion: dropped {len(dropped)} subject(s) lacking a value for some "
        f"level: {'; '.join(details)}"
    )
    return incomplete.to_numpy(), dropped, [note]


def repeated_measures(df: pd.DataFrame, *, dv: str, within: str, subject: str) -> RepeatedMeasures:
    """Validate a long-format frame and reshape it to the complete-case wide table.

    Parameters
    ----------
    df : pandas.DataFrame
        Long format: one row per subject and level (several rows per cell are averaged).
    dv, within, subject : str
        Columns holding the dependent variable (numeric; NaN = missing), the within-subject
        factor and the subject id.

    Returns
    -------
    RepeatedMeasures
        The (n, k) table of complete subjects, the labels, who was dropped and why.

    Raises
    ------
    ValueError
        A column is missing (the message lists the available ones), the dv is not numeric
        (naming the first offending row and value), an id cell is empty, there are fewer than
        two levels, or fewer than two subjects have every level.

    Notes
    -----
    In R: ``aggregate(dv ~ subject + within, df, mean)`` then ``reshape(..., direction =
    "wide")`` and ``na.omit``; in SPSS the data are entered wide, one column per level, and
    GLM drops incomplete cases.
    """
    _check_columns(df, dv=dv, within=within, subject=subject)
    long = pd.DataFrame(
        {
            "subject": _labels(df[subject], subject),
            "level": _labels(df[within], within),
            "y": _numeric_dv(df[dv], dv),
        }
    )
    levels = _levels(long, within)
    subjects_all = tuple(pd.unique(long["subject"]))
    wide, notes = _wide(long, subjects_all, levels)
    incomplete, dropped, dropped_note = _incomplete(wide, levels)
    notes += dropped_note
    complete = wide.loc[~incomplete]
    if len(complete) < 2:
        raise ValueError(
            f"only {len(complete)} subject(s) in column {subject!r} have a {dv!r} value for "
            f"every level of {within!r} ({_quoted(levels)}); need at least two"
            + (f" (dropped: {_quoted(dropped)})" if dropped else "")
        )
    # row-major, as the groupby table was: numpy's sums depend on the layout in the last bit
    y = np.ascontiguousarray(complete.to_numpy(dtype=float))
    y.setflags(write=False)
    return RepeatedMeasures(
        y=y,
        levels=tuple(str(level) for level in levels),
        subjects=tuple(str(s) for s in complete.index),
        dropped_subjects=dropped,
        warnings=tuple(notes),
    )


def descriptives(df: pd.DataFrame, *, dv: str, within: str, subject: str) -> pd.DataFrame:
    """Mean, SD, SE and n of the dv per level, on the complete cases.

    Parameters
    ----------
    df : pandas.DataFrame
        Long format, see :func:`repeated_measures`.
    dv, within, subject : str
        Column names.

    Returns
    -------
    pandas.DataFrame
        Indexed by level (first-appearance order, index name ``within``), columns ``mean``,
        ``sd`` (ddof = 1), ``se`` = sd / sqrt(n), ``n`` (complete subjects), in the dv's unit.

    Notes
    -----
    In R: ``aggregate(dv ~ within, wide_complete, function(x) c(mean(x), sd(x),
    sd(x) / sqrt(length(x))))``; in SPSS: GLM Repeated Measures, Options > Descriptive
    statistics (SPSS prints SD, not SE).
    """
    data = repeated_measures(df, dv=dv, within=within, subject=subject)
    return _descriptives(data, within)


def _descriptives(data: RepeatedMeasures, within: str) -> pd.DataFrame:
    n = data.y.shape[0]
    sd = data.y.std(axis=0, ddof=1)
    frame = pd.DataFrame(
        {"mean": data.y.mean(axis=0), "sd": sd, "se": sd / math.sqrt(n), "n": n},
        index=pd.Index(list(data.levels), name=within),
    )
    return frame
