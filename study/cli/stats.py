"""``asa stats``: repeated-measures statistics for any long-format CSV.

A thin shell over :func:`analysis.tables.read_long_csv`, :func:`analysis.stats.analyse` and
:func:`analysis.tables.format_summary`. Errors about the data name the file; with ``--json``
stdout carries the one object and nothing else (warnings also go to stderr).
"""

from __future__ import annotations

import json
from pathlib import Path

import click

from analysis.stats import GATES, POSTHOC, POSTHOC_GATES, TESTS, analyse
from analysis.tables import SameColumnError, format_summary, read_long_csv


@click.command()
@click.option(
    "--csv",
    "csv_path",
    required=True,
    type=click.Path(path_type=Path),
    help="Long-format CSV: one row per subject and level.",
)
@click.option("--dv", required=True, help="Column of the dependent variable (numeric).")
@click.option("--within", required=True, help="Column of the within-subject factor.")
@click.option("--subject", required=True, help="Column of the subject id.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object and nothing else.")
@click.option(
    "--alpha",
    type=click.FloatRange(0.0, 1.0, min_open=True, max_open=True),
    default=0.05,
    show_default=True,
    help="Significance level of the ANOVA gate and the LSD pairs (CI level 1 - alpha).",
)
@click.option(
    "--gate",
    type=click.Choice(GATES),
    default="auto",
    show_default=True,
    help="Which p gates the post-hoc tests: auto = Greenhouse-Geisser when Mauchly's p < .05.",
)
@click.option(
    "--test",
    type=click.Choice(TESTS),
    default="rm_anova",
    show_default=True,
    help="The planned omnibus test; the other is reported too. auto = Friedman for whole "
    "numbers with many ties (counts, rating items), else RM-ANOVA.",
)
@click.option(
    "--posthoc",
    type=click.Choice(POSTHOC),
    default="lsd_paired",
    show_default=True,
    help="The planned post-hoc family of the RM-ANOVA (all four are in --json). LSD is "
    "protected for three levels only; holm or bonferroni beyond.",
)
@click.option(
    "--posthoc-gate",
    type=click.Choice(POSTHOC_GATES),
    default="auto",
    show_default=True,
    help="Which post-hoc families run only after the omnibus test rejects: auto = the LSD "
    "forms (Fisher's protection) while Holm, Bonferroni and Friedman's Wilcoxon-Holm pairs "
    "always run; omnibus = every family; none = no family (unprotected LSD).",
)
@click.option(
    "--order",
    default=None,
    help="Column of each row's position in the subject's order (1, 2, ...): adds the "
    "order-effect tests and the position covariate of the mixed model.",
)
def stats(
    csv_path: Path,
    dv: str,
    within: str,
    subject: str,
    as_json: bool,
    alpha: float,
    gate: str,
    test: str,
    posthoc: str,
    posthoc_gate: str,
    order: str | None,
) -> None:
    """Statistics of DV by WITHIN for any long-format CSV: descriptives, repeated-measures
    ANOVA with Mauchly's test and Greenhouse-Geisser, eta squared with CIs, the post-hoc
    pairs (Fisher's LSD paired and pooled, Holm, Bonferroni) with mean differences and
    Cohen's d_z with CIs, assumption checks (Shapiro-Wilk, outliers), Friedman with
    Kendall's W and Wilcoxon-Holm pairs, a linear mixed model (random intercept per
    subject) with its likelihood-ratio test, and with --order the order effects.

    Subjects lacking a level are dropped from every test but the mixed model (named in a
    warning); several rows for one subject and level are averaged.
    """
    try:
        frame = read_long_csv(csv_path, dv=dv, within=within, subject=subject, order=order)
    except SameColumnError:
        raise ValueError(
            f"{csv_path}: --dv, --within and --subject must name three different columns, "
            f"got {dv!r}, {within!r}, {subject!r}"
        ) from None
    options = {
        "alpha": alpha, "gate": gate, "test": test, "posthoc": posthoc,
        "posthoc_gate": posthoc_gate, "order": order,
    }  # fmt: skip
    try:
        result = analyse(frame, dv=dv, within=within, subject=subject, **options)
    except ValueError as error:
        raise ValueError(f"{csv_path}: {error}") from error
    if as_json:
        for warning in result["warnings"]:
            click.echo(f"asa: warning: {warning}", err=True)
        click.echo(json.dumps(result, allow_nan=False))
    else:
        click.echo(format_summary(result, dv=dv, within=within, alpha=alpha, gate=gate))
