"""Linear mixed models of one metric: mode as a fixed effect, position in the order as a
covariate, a random intercept per participant (statsmodels MixedLM), with likelihood-ratio
tests from ML fits; and the order-effect checks (position, mode x position) built on the same
fits. Issue 21; not in the thesis (Sec. 7.6.2 uses the RM-ANOVA on complete cases only).

Unlike the RM-ANOVA these keep participants who lack a mode: every observed cell counts.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
from scipy import stats

from analysis.stats.design import _labels, _numeric_dv

CAVEAT = (
    "likelihood-ratio tests of ML fits are anti-conservative with few participants (their p "
    "too small; Pinheiro & Bates 2000, Sec. 2.4.1); read them beside the RM-ANOVA, or use "
    "Kenward-Roger F tests (R: lmerTest, afex::mixed) in a confirmatory analysis"
)


def cells(
    df: pd.DataFrame, *, dv: str, within: str, subject: str, order: str | None = None
) -> pd.DataFrame:
    """One row per observed (subject, level) cell: the long frame the mixed models fit.

    Parameters
    ----------
    df : pandas.DataFrame
        Long format (validated by :func:`analysis.stats.repeated_measures` first).
    dv, within, subject : str
        Column names.
    order : str, optional
        Column of the position of the level in the subject's order (1 = first), numeric.

    Returns
    -------
    pandas.DataFrame
        Columns ``subject``, ``level`` (str), ``y`` (the cell's mean) and, with ``order``,
        ``position`` (float); rows with a missing dv dropped; first-appearance order.

    Raises
    ------
    ValueError
        The order column is missing, not numeric, empty for an observed cell, or differs
        between the rows of one cell.
    """
    frame = pd.DataFrame(
        {
            "subject": _labels(df[subject], subject),
            "level": _labels(df[within], within),
            "y": _numeric_dv(df[dv], dv),
        },
        index=df.index,
    )
    if order is not None:
        frame["position"] = _positions(df, order, observed=frame["y"].notna())
    frame = frame[frame["y"].notna()]
    grouped = frame.groupby(["subject", "level"], sort=False)
    out = grouped["y"].mean().reset_index()
    if order is not None:
        spread = grouped["position"].agg(lambda s: s.max() - s.min())
        if (spread > 0).any():
            who, where = spread[spread > 0].index[0]
            raise ValueError(
                f"column {order!r}: subject {who!r}, level {where!r} has rows with different "
                f"positions; a cell has one position in the order"
            )
        out["position"] = grouped["position"].first().to_numpy()
    return out


def _positions(df: pd.DataFrame, order: str, *, observed: pd.Series) -> pd.Series:
    """The order column as numbers; an observed cell without a numeric position is an error."""
    if order not in df.columns:
        available = ", ".join(repr(str(c)) for c in df.columns)
        raise ValueError(f"column {order!r} (order) not found; available columns: {available}")
    values = pd.to_numeric(df[order], errors="coerce").astype(float)
    bad = (values.isna() | np.isinf(values)) & observed
    if bad.any():
        row = df.index[np.flatnonzero(bad.to_numpy())[0]]
        raise ValueError(
            f"column {order!r}: row {row}: {df.loc[row, order]!r} is not a position "
            f"(a number: 1 for the first level in the subject's order, 2 for the second, ...)"
        )
    return values


def _dummies(codes: pd.Series, labels: list, prefix: str) -> pd.DataFrame:
    """Treatment-coded indicator columns of every label but the first (the reference)."""
    return pd.DataFrame(
        {f"{prefix}{_label(label)}": (codes == label).astype(float) for label in labels[1:]},
        index=codes.index,
    )


def design(data: pd.DataFrame, terms: tuple[str, ...], levels: list[str]) -> pd.DataFrame:
    """The fixed-effect design matrix of ``terms`` (R's default treatment contrasts).

    Terms: "mode" (indicators ``mode<level>``), "position" (numeric covariate),
    "position_factor" (indicators ``position<p>``), "mode:position_factor" (products).
    Columns aliased with earlier ones are dropped (as lme4 does for a rank-deficient matrix).
    """
    parts = [pd.DataFrame({"(Intercept)": 1.0}, index=data.index)]
    mode = _dummies(data["level"], levels, "mode")
    positions = sorted(data["position"].unique()) if "position" in data else []
    pos = _dummies(data["position"], positions, "position") if positions else None
    for term in terms:
        if term == "mode":
            parts.append(mode)
        elif term == "position":
            parts.append(data[["position"]].astype(float))
        elif term == "position_factor":
            parts.append(pos)
        elif term == "mode:position_factor":
            products = {f"{m}:{p}": mode[m] * pos[p] for m in mode for p in pos}
            parts.append(pd.DataFrame(products, index=data.index))
        else:
            raise ValueError(f"unknown term {term!r}")
    return _independent(pd.concat(parts, axis=1))


def _independent(x: pd.DataFrame) -> pd.DataFrame:
    """``x`` without the columns that are linear combinations of the columns before them."""
    keep: list[str] = []
    for column in x.columns:
        trial = x[[*keep, column]].to_numpy()
        if np.linalg.matrix_rank(trial, tol=1e-9 * max(1.0, np.abs(trial).max())) == len(keep) + 1:
            keep.append(column)
    return x[keep]


def _exact(data: pd.DataFrame, x: pd.DataFrame) -> bool:
    """Whether y ~ x + subject fits the data exactly (residual variance 0: no mixed model)."""
    subjects = pd.get_dummies(data["subject"], dtype=float).to_numpy()
    full = np.column_stack([x.to_numpy(), subjects])
    y = data["y"].to_numpy(dtype=float)
    beta, *_ = np.linalg.lstsq(full, y, rcond=None)
    rss = float(np.sum((y - full @ beta) ** 2))
    scale = 64.0 * np.finfo(float).eps * max(1.0, float(np.max(np.abs(y))))
    return rss <= y.size * scale**2


def fit(data: pd.DataFrame, x: pd.DataFrame, *, reml: bool):
    """statsmodels MixedLM of y on x with a random intercept per subject; the results object.

    L-BFGS from statsmodels' default start; Powell's method too when L-BFGS reports no
    convergence, keeping the fit of higher (restricted) likelihood. In R: ``lme4::lmer(y ~ x + (1 |
    subject), REML = reml)``.
    """
    from statsmodels.regression.mixed_linear_model import MixedLM

    model = MixedLM(data["y"].to_numpy(), x.to_numpy(), groups=data["subject"].to_numpy())
    best = None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # boundary and convergence notes: we compare fits
        for method in ("lbfgs", "powell"):
            try:
                result = model.fit(reml=reml, method=method, maxiter=2000)
            except (np.linalg.LinAlgError, ValueError):  # pragma: no cover - degenerate data
                continue
            if best is None or result.llf > best.llf + 1e-10:
                best = result
            if result.converged:
                break
    return best


def lrt(data: pd.DataFrame, full: tuple[str, ...], reduced: tuple[str, ...], levels) -> dict:
    """Likelihood-ratio test of nested fixed-effect models from ML fits (reml=False).

    chi2 = 2 (logLik_full - logLik_reduced), df = difference in fixed-effect columns,
    p = P(chi2_df > chi2). In R: ``anova(lmer(full, REML = FALSE), lmer(reduced, REML =
    FALSE))``.
    """
    x_full, x_reduced = design(data, full, levels), design(data, reduced, levels)
    df = x_full.shape[1] - x_reduced.shape[1]
    out = {"chi2": None, "df": df, "p": None, "loglik_full": None, "loglik_reduced": None}
    if df == 0 or _exact(data, x_full):
        return out
    big, small = fit(data, x_full, reml=False), fit(data, x_reduced, reml=False)
    if big is None or small is None:  # pragma: no cover - statsmodels failed on both methods
        return out
    chi2 = max(0.0, 2.0 * (big.llf - small.llf))
    out.update(chi2=chi2, p=float(stats.chi2.sf(chi2, df)))
    out.update(loglik_full=float(big.llf), loglik_reduced=float(small.llf))
    return out


def _fixed(result, x: pd.DataFrame) -> list[dict]:
    return [
        {"term": name, "estimate": float(b), "se": float(se)}
        for name, b, se in zip(x.columns, result.fe_params, result.bse_fe, strict=True)
    ]


def mixed_model(data: pd.DataFrame, levels: list[str]) -> dict:
    """The mixed model of one metric and the likelihood-ratio test of mode.

    None for every figure when y ~ mode + subject fits exactly (residual variance 0).

    Model: y_ij = mu + alpha_mode(ij) [+ beta * position_ij] + b_i + e_ij, b_i ~ N(0,
    var_subject), e_ij ~ N(0, var_residual); treatment contrasts, the first level the
    reference; position (1, 2, ...) linear when the data have it.

    Parameters
    ----------
    data : pandas.DataFrame
        From :func:`cells`.
    levels : list of str
        Level labels, the first the reference.

    Returns
    -------
    dict
        ``formula``, ``n_obs``, ``n_subjects``, ``incomplete_subjects`` (kept, lacking some
        level), ``lrt`` {chi2, df, p, loglik_full, loglik_reduced} of mode (ML fits),
        ``fixed`` [{term, estimate, se}] and ``var_subject``, ``var_residual`` (REML fit),
        ``caveat``.

    Notes
    -----
    In R: ``m1 <- lmer(y ~ mode + position + (1 | subject), REML = FALSE)``, ``m0`` without
    mode, ``anova(m0, m1)``; estimates from the REML fit, ``summary(lmer(...))``.
    """
    terms = ("mode", "position") if "position" in data else ("mode",)
    reduced = tuple(t for t in terms if t != "mode")
    per_subject = data.groupby("subject", sort=False)["level"].nunique()
    rhs = " + ".join(terms)
    out = {
        "formula": f"y ~ {rhs} + (1 | subject)",
        "n_obs": int(len(data)),
        "n_subjects": int(per_subject.size),
        "incomplete_subjects": [str(s) for s in per_subject.index[per_subject < len(levels)]],
        "lrt": lrt(data, terms, reduced, levels),
        "fixed": [],
        "var_subject": None,
        "var_residual": None,
        "caveat": CAVEAT,
    }
    x = design(data, terms, levels)
    result = None if _exact(data, x) else fit(data, x, reml=True)
    if result is not None:
        out["fixed"] = _fixed(result, x)
        out["var_subject"] = float(np.asarray(result.cov_re)[0, 0])
        out["var_residual"] = float(result.scale)
    return out


def order_effects(data: pd.DataFrame, levels: list[str]) -> dict:
    """Order checks of one metric: position, and mode x position, by likelihood-ratio tests.

    Position enters as a factor (first, second, ...). ``position``: y ~ mode + position vs
    y ~ mode; ``mode_x_position``: y ~ mode * position vs y ~ mode + position; ML fits with a
    random intercept per participant. Cells never observed make interaction columns aliased;
    they are dropped and the df says how many remain.

    Returns
    -------
    dict
        ``position`` and ``mode_x_position``, each {chi2, df, p, loglik_full,
        loglik_reduced}; ``position_means`` {position: mean of y}; ``caveat``.

    Notes
    -----
    In R: ``anova(lmer(y ~ mode + factor(position) + (1 | subject), REML = FALSE),
    lmer(y ~ mode * factor(position) + (1 | subject), REML = FALSE))``.
    """
    means = data.groupby("position")["y"].mean()
    return {
        "position": lrt(data, ("mode", "position_factor"), ("mode",), levels),
        "mode_x_position": lrt(
            data,
            ("mode", "position_factor", "mode:position_factor"),
            ("mode", "position_factor"),
            levels,
        ),
        "position_means": {_label(p): float(m) for p, m in means.items()},
        "caveat": CAVEAT,
    }


def _label(value) -> str:
    """A level or position as text; whole-number positions without ".0"."""
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return str(value)
