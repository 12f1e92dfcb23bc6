"""Long-format CSV in, readable statistics out: the I/O edge of :mod:`analysis.stats`.

:func:`read_long_csv` validates a CSV and names the file, the column and the line of anything
wrong; :func:`format_p`, :func:`apa_anova` and :func:`format_summary` turn the object of
:func:`analysis.stats.analyse` into APA-style text (thesis Sec. 7.6.2).
"""

from __future__ import annotations

import errno
import math
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.stats.apa import _no_leading_zero, format_p

__all__ = ["SameColumnError", "apa_anova", "format_p", "format_summary", "read_long_csv"]

MAX_MAGNITUDE = 1e15  # |x| of a dependent variable; beyond it sums of squares lose every digit


class SameColumnError(ValueError):
    """``dv``, ``within`` and ``subject`` of :func:`read_long_csv` name fewer than three
    different columns (a ``ValueError``; the CLI words it with its flags)."""


def read_long_csv(
    path: str | Path, *, dv: str, within: str, subject: str, order: str | None = None
) -> pd.DataFrame:
    """Read and validate a long-format CSV: one row per subject and level.

    Parameters
    ----------
    path : str or Path
        The CSV file (comma-separated, UTF-8, header row).
    dv, within, subject : str
        Columns holding the dependent variable, the within-subject factor and the subject id.
    order : str, optional
        Column holding each row's position in the subject's order of levels (1 = first).

    Returns
    -------
    pandas.DataFrame
        Columns ``subject`` and ``within`` as str, ``dv`` as float64 (NaN = missing) and
        ``order`` as float64 when given, in file order, under their original names; the
        index is the file's line number.

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    ValueError
        ``"FILE: ..."``: not a readable CSV, a column missing (listing the available ones),
        the same column given twice (:class:`SameColumnError`), an empty id cell, a
        non-numeric or infinite dv value (naming its line and value), or fewer than two levels.
    """
    path = Path(path)
    raw = _read_raw(path)
    _check_roles(path, [str(c) for c in raw.columns], dv=dv, within=within, subject=subject)
    if order is not None:
        _check_order_role(path, [str(c) for c in raw.columns], order, (dv, within, subject))
    for column in (subject, within):
        _check_ids(path, raw, column)
    values = _dv_values(path, raw, dv)
    positions = _positions(path, raw, order, observed=values.notna()) if order else None
    levels = list(pd.unique(raw[within].str.strip()))
    if len(levels) < 2:
        found = ", ".join(repr(level) for level in levels) or "none"
        raise ValueError(
            f"{path}: column {within!r}: only {len(levels)} level ({found}); a "
            f"repeated-measures ANOVA needs at least two"
        )
    frame = pd.DataFrame(
        {
            subject: raw[subject].str.strip(),
            within: raw[within].str.strip(),
            dv: values.astype(float),
        },
        index=raw.index,
    )
    if positions is not None:
        frame[order] = positions
    return frame


def _check_order_role(path: Path, columns: list[str], order: str, others: tuple) -> None:
    if order not in columns:
        available = ", ".join(repr(c) for c in columns)
        raise ValueError(
            f"{path}: column {order!r} (order) not found; available columns: {available}"
        )
    if order in others:
        raise ValueError(
            f"{path}: the order column {order!r} is also the dv, within or subject column"
        )


def _positions(path: Path, raw: pd.DataFrame, order: str, *, observed: pd.Series) -> pd.Series:
    """The order column as numbers; a row with a dv value needs a finite position."""
    text = raw[order].str.strip()
    values = pd.to_numeric(text, errors="coerce").astype(float)
    bad = (values.isna() | np.isinf(values)) & observed
    if bad.any():
        line = int(raw.index[np.flatnonzero(bad.to_numpy())[0]])
        raise ValueError(
            f"{path}: column {order!r} line {line}: {raw.loc[line, order]!r} is not a position "
            f"(a number: 1 for the level the subject had first, 2 for the second, ...)"
        )
    return values


def _read_raw(path: Path) -> pd.DataFrame:
    """Every cell as text, indexed by the file's line number (header = line 1), blank lines
    dropped."""
    if not path.exists():
        raise FileNotFoundError(errno.ENOENT, "no such file", str(path))
    if path.is_dir():
        raise ValueError(f"{path}: is a directory, expected a CSV file")
    try:
        with warnings.catch_warnings():
            # pandas would otherwise turn extra leading fields into an index, or drop them.
            warnings.simplefilter("error", pd.errors.ParserWarning)
            raw = pd.read_csv(
                path,
                dtype=str,
                index_col=False,
                skip_blank_lines=False,
                skipinitialspace=True,
                encoding="utf-8",
            )
    except pd.errors.ParserWarning:
        raise ValueError(
            f"{path}: not a valid CSV (a row has more fields than the header)"
        ) from None
    except UnicodeDecodeError as error:
        raise ValueError(f"{path}: not a UTF-8 text file ({error.reason})") from None
    except pd.errors.EmptyDataError:
        raise ValueError(f"{path}: empty file; expected a header row naming the columns") from None
    except pd.errors.ParserError as error:
        raise ValueError(f"{path}: not a valid CSV ({' '.join(str(error).split())})") from None
    raw.index = pd.RangeIndex(2, len(raw) + 2, name="line")  # header is line 1
    return raw.dropna(how="all")  # blank lines


def _check_roles(path: Path, columns: list[str], *, dv: str, within: str, subject: str) -> None:
    available = ", ".join(repr(c) for c in columns) or "none"
    roles = {"dv": dv, "within": within, "subject": subject}
    for role, column in roles.items():
        if column not in columns:
            raise ValueError(
                f"{path}: column {column!r} ({role}) not found; available columns: {available}"
            )
    if len(set(roles.values())) < 3:
        raise SameColumnError(
            f"{path}: dv, within and subject must name three different columns, "
            f"got {dv!r}, {within!r}, {subject!r}"
        )


def _check_ids(path: Path, raw: pd.DataFrame, column: str) -> None:
    empty = raw[column].isna() | (raw[column].str.strip() == "")
    if empty.any():
        line = int(raw.index[np.flatnonzero(empty.to_numpy())[0]])
        raise ValueError(f"{path}: column {column!r} line {line}: empty cell")


def _dv_values(path: Path, raw: pd.DataFrame, dv: str) -> pd.Series:
    """The dv as numbers (NaN = missing); a non-number or an infinity is an error."""
    text = raw[dv].str.strip()
    values = pd.to_numeric(text, errors="coerce")
    bad = values.isna() & text.notna() & (text != "")
    if bad.any():
        line = int(raw.index[np.flatnonzero(bad.to_numpy())[0]])
        raise ValueError(
            f"{path}: column {dv!r} line {line}: {raw.loc[line, dv]!r} is not a number "
            f"(leave the cell empty or write NA for a missing value)"
        )
    infinite = np.isinf(values.to_numpy(dtype=float))
    if infinite.any():
        line = int(raw.index[np.flatnonzero(infinite)[0]])
        raise ValueError(f"{path}: column {dv!r} line {line}: {raw.loc[line, dv]!r} is not finite")
    huge = np.abs(values.to_numpy(dtype=float)) > MAX_MAGNITUDE
    if huge.any():  # squares and sums of squares would overflow or lose every digit
        line = int(raw.index[np.flatnonzero(huge)[0]])
        raise ValueError(
            f"{path}: column {dv!r} line {line}: {raw.loc[line, dv]!r} is too large "
            f"(at most {MAX_MAGNITUDE:g} in size)"
        )
    return values


# --------------------------------------------------------------------------------------------
# Text
# --------------------------------------------------------------------------------------------


def _num(value: float | None, digits: int = 2, *, zero: bool = True) -> str:
    if value is None or not math.isfinite(value):
        return "n/a"
    text = f"{value:.{digits}f}"
    return text if zero else _no_leading_zero(text)


def _uses_gg(result: dict) -> bool:
    """Whether the gate took the Greenhouse-Geisser p with eps < 1 (corrected dfs differ)."""
    eps = result["greenhouse_geisser"]["eps"]
    return result["p_gate_source"] == "greenhouse_geisser" and eps is not None and eps < 1.0


def apa_anova(result: dict, *, alpha: float | None = None) -> str:
    """The APA line of one analysis, e.g. ``"F(2, 34) = 25.76, p < .001, eta_p^2 = .60"``.

    Parameters
    ----------
    result : dict
        The object of :func:`analysis.stats.analyse`.
    alpha : the significance level, for p near it (:func:`format_p`).

    Returns
    -------
    str
        With the Greenhouse-Geisser dfs (eps-scaled, two decimals) and p when the gate used
        them, marked "(Greenhouse-Geisser)"; "F undefined (SS_error = 0)" when F is null.
    """
    anova = result["anova"]
    df1, df2 = anova["df_effect"], anova["df_error"]
    if anova["F"] is None:
        return f"F({df1}, {df2}) undefined (SS_error = 0)"
    if _uses_gg(result):
        eps = result["greenhouse_geisser"]["eps"]
        dfs, suffix = f"{eps * df1:.2f}, {eps * df2:.2f}", " (Greenhouse-Geisser)"
    else:
        dfs, suffix = f"{df1}, {df2}", ""
    return (
        f"F({dfs}) = {anova['F']:.2f}, p {format_p(result['p_gate'], alpha=alpha)}, "
        f"eta_p^2 = {_num(anova['np2'], zero=False)}{suffix}"
    )


def _table(header: list[str], rows: list[list[str]], *, left: int = 1) -> list[str]:
    """Aligned text columns; the first ``left`` columns (labels) flush left, numbers right."""
    widths = [max(len(cell) for cell in column) for column in zip(header, *rows, strict=True)]
    lines = []
    for row in [header, *rows]:
        cells = [
            cell.ljust(width) if i < left else cell.rjust(width)
            for i, (cell, width) in enumerate(zip(row, widths, strict=True))
        ]
        lines.append("  " + "  ".join(cells).rstrip())
    return lines


def _pair_table(pairs: list[dict], alpha: float | None = None) -> list[str]:
    rows = [
        [
            pair["a"],
            pair["b"],
            _num(pair["diff"], 3),
            _num(pair["t"], 2),
            str(pair["df"]),
            format_p(pair["p"], alpha=alpha).replace("= ", ""),
            f"[{_num(pair['ci_low'], 3)}, {_num(pair['ci_high'], 3)}]",
            "*" if pair["significant"] else "",
        ]
        for pair in pairs
    ]
    return _table(["a", "b", "diff (a-b)", "t", "df", "p", "CI", "sig"], rows, left=2)


def format_summary(
    result: dict,
    *,
    dv: str = "dv",
    within: str = "within",
    alpha: float = 0.05,
    gate: str = "auto",
) -> str:
    """A plain-text report of one analysis: descriptives, ANOVA, sphericity, GG, post hoc.

    Parameters
    ----------
    result : dict
        The object of :func:`analysis.stats.analyse`.
    dv, within : str
        Names shown in the headings.
    alpha : float
        The significance level the analysis used (for the CI level and the gate line).
    gate : str
        The gate rule the analysis used.

    Returns
    -------
    str
        Several lines, no trailing newline.
    """
    levels = result["levels"]
    dropped = result["dropped_subjects"]
    out = [
        f"{dv} by {within}: {result['n_subjects']} subjects, {len(levels)} levels"
        + (f" ({len(dropped)} dropped: {', '.join(dropped)})" if dropped else ""),
        "",
        "Descriptives",
    ]
    out += _descriptives_lines(result, within)
    if "planned" in result:
        planned = result["planned"]
        out += ["", f"Planned test: {planned['test']} ({planned['reason']}); the other follows"]
    out += _anova_lines(result, alpha=alpha, gate=gate)
    out += _posthoc_lines(result, alpha)
    if "planned" in result:  # issue 21's additions
        out += _effect_lines(result)
        out += _friedman_lines(result, alpha)
        out += _assumption_lines(result)
        out += _model_lines(result)
    if result["warnings"]:
        out += ["", "Warnings"]
        out += [f"  - {warning}" for warning in result["warnings"]]
    return "\n".join(out)


def _descriptives_lines(result: dict, within: str) -> list[str]:
    rows = [
        [
            level,
            str(d["n"]),
            _num(d["mean"], 3),
            _num(d["sd"], 3),
            _num(d["se"], 3),
        ]
        for level, d in result["descriptives"].items()
    ]
    return _table([within, "n", "mean", "sd", "se"], rows)


def _anova_lines(result: dict, *, alpha: float, gate: str) -> list[str]:
    """The ANOVA, Mauchly, Greenhouse-Geisser and gate lines."""
    anova, sph, gg = result["anova"], result["sphericity"], result["greenhouse_geisser"]
    out = [
        "",
        "Repeated-measures ANOVA",
        f"  {apa_anova(result)}, eta_G^2 = {_num(anova['ng2'], zero=False)}",
        f"  uncorrected: F({anova['df_effect']}, {anova['df_error']}) = {_num(anova['F'])}, "
        f"p {format_p(anova['p_unc'])}; SS_effect = {_num(anova['ss_effect'], 4)}, "
        f"SS_error = {_num(anova['ss_error'], 4)}, MS_error = {_num(anova['ms_error'], 4)}",
    ]
    if sph["W"] is None:
        out.append("  Mauchly's test: undefined")
    else:
        verdict = "violated" if sph["violated"] else "not violated"
        out.append(
            f"  Mauchly's test: W = {_num(sph['W'], 3)}, chi2({sph['dof']}) = "
            f"{_num(sph['chi2'])}, p {format_p(sph['p'])} (sphericity {verdict})"
        )
    out.append(f"  Greenhouse-Geisser: eps = {_num(gg['eps'], 3)}, p {format_p(gg['p'])}")
    verdict = "significant" if result["significant"] else "not significant"
    out.append(
        f"  gate ({gate}): p {format_p(result['p_gate'])} -> {verdict} at alpha = "
        f"{_no_leading_zero(f'{alpha:g}')}"
    )
    return out


def _posthoc_lines(result: dict, alpha: float) -> list[str]:
    """Both LSD tables and the planned Holm or Bonferroni table, each when it ran, or the
    line saying the planned family was not run."""
    if not result["posthoc"]["ran"]:
        return ["", "Post hoc: not run (the gate did not pass)"]
    anova, posthoc = result["anova"], result["posthoc"]
    confidence = f"{100 * (1 - alpha):g}% CI"
    n = result["n_subjects"]
    out = []
    if posthoc["lsd_paired"]:
        out += [
            "",
            f"Fisher's LSD, paired (each pair's own differences, df = {n - 1}; {confidence})",
        ]
        out += _pair_table(posthoc["lsd_paired"], alpha)
        out += [
            "",
            f"Fisher's LSD, pooled (MS_error = {_num(anova['ms_error'], 4)}, "
            f"df = {anova['df_error']}; {confidence})",
        ]
        out += _pair_table(posthoc["lsd_pooled"], alpha)
    else:
        out += ["", "Fisher's LSD: not run (the gate did not pass)"]
    planned = result.get("posthoc_planned", "lsd_paired")
    if planned in ("holm", "bonferroni"):
        m = len(posthoc[planned])
        out += ["", f"Paired t-tests, {planned.capitalize()} over {m} pairs (CI Bonferroni)"]
        out += _pair_table(posthoc[planned], alpha)
    if result.get("posthoc_warning"):
        out += [f"  note: {result['posthoc_warning']}"]
    return out


def _effect_lines(result: dict) -> list[str]:
    """eta squared with its CI and the pairs' mean differences and d_z with CIs."""
    sizes = result["effect_sizes"]
    np2, level = sizes["np2"], sizes["pair_ci_level"]
    out = [
        "",
        "Effect sizes",
        f"  eta_p^2 = {_num(np2['value'], 3)}, {100 * np2['ci_level']:g}% CI "
        f"[{_num(np2['ci_low'], 3)}, {_num(np2['ci_high'], 3)}] ({np2['method']}); "
        f"eta_G^2 = {_num(sizes['ng2']['value'], 3)}",
        f"  pairs: mean difference and Cohen's d_z, {100 * level:g}% CIs "
        f"(d_z: {sizes['dz_ci_method']})",
    ]
    rows = [
        [
            e["a"],
            e["b"],
            _num(e["diff"], 3),
            f"[{_num(e['ci_low'], 3)}, {_num(e['ci_high'], 3)}]",
            _num(e["dz"], 2),
            f"[{_num(e['dz_ci_low'], 2)}, {_num(e['dz_ci_high'], 2)}]",
        ]
        for e in result["pairs"]
    ]
    return out + _table(["a", "b", "diff (a-b)", "CI", "d_z", "CI"], rows, left=2)


def _friedman_lines(result: dict, alpha: float) -> list[str]:
    friedman = result["friedman"]
    out = ["", "Friedman test (ranks within subject)", f"  {result['apa']['friedman']}"]
    if not friedman["posthoc"]["ran"]:
        return out + ["  Wilcoxon signed-rank pairs: not run (Friedman not significant, gated)"]
    rows = [
        [
            w["a"],
            w["b"],
            _num(w["median_diff"], 3),
            _num(w["V"], 1),
            str(w["n"]),
            format_p(w["p_unc"]).replace("= ", ""),
            format_p(w["p"], alpha=alpha).replace("= ", ""),
            "*" if w["significant"] else "",
        ]
        for w in friedman["posthoc"]["wilcoxon_holm"]
    ]
    header = ["a", "b", "median diff", "V", "n", "p", "p (Holm)", "sig"]
    return out + ["  Wilcoxon signed-rank pairs, Holm"] + _table(header, rows, left=2)


def _assumption_lines(result: dict) -> list[str]:
    checks = result["assumptions"]
    out = ["", "Assumptions"]
    for pair in checks["normality"]["pairs"]:
        verdict = " (not normal)" if pair["violated"] else ""
        out.append(
            f"  Shapiro-Wilk {pair['a']} - {pair['b']}: W = {_num(pair['W'], 3)}, "
            f"p {format_p(pair['p'])}{verdict}"
        )
    outliers = checks["outliers"]
    out.append(
        f"  outliers (|studentised residual| > {outliers['limit']:g}): {outliers['count']}"
        + (f", max |t| = {_num(outliers['max_abs'])}" if outliers["max_abs"] is not None else "")
    )
    return out


def _model_lines(result: dict) -> list[str]:
    mixed, apa = result["mixed"], result["apa"]
    out = []
    if mixed is not None:
        out += ["", f"Mixed model {mixed['formula']}", f"  mode: {apa['mixed']}"]
        if mixed["incomplete_subjects"]:
            out.append(f"  kept with a missing level: {', '.join(mixed['incomplete_subjects'])}")
        out.append(f"  caveat: {mixed['caveat']}")
    if result["order"] is not None:
        out += ["", "Order effects (mixed-model likelihood ratios)", f"  {apa['order']}"]
    return out
