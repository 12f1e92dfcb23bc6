"""``analysis.R``: the report's planned tests as an R script a reviewer can run beside the
report's CSV tables (issue 21).

The script reads ``tables/trials.csv`` (one row per counted main trial) and, per planned
metric, runs what :func:`analysis.stats.analyse` computed: the repeated-measures ANOVA
with Mauchly and Greenhouse-Geisser (afex), the planned post-hoc family (emmeans, paired
model), Friedman with Wilcoxon pairs (Holm), and the linear mixed model's likelihood-ratio
test of mode (lme4, ML). ``tests/r/oracle.R`` is the full oracle the statistics are tested
against; this script is its short, readable form for one study.
"""

from __future__ import annotations

# emmeans adjustment of each post-hoc family (both LSD forms are unadjusted; the pooled
# one uses the univariate model's error term)
_ADJUST = {"lsd_paired": "none", "lsd_pooled": "none", "holm": "holm", "bonferroni": "bonferroni"}

_TEMPLATE = """#!/usr/bin/env Rscript
# The planned analysis of study '{name}' (protocol SHA-256 {sha}), written by asa report.
# Run it in the report folder:  Rscript analysis.R
# Needs R >= 4.2 with afex, emmeans, lme4 (Debian: r-cran-afex r-cran-emmeans r-cran-lme4).
# The secondary-task metrics' baseline level is not in trials.csv: here they are tested
# over the driving modes only.
suppressPackageStartupMessages({{ library(afex); library(emmeans); library(lme4) }})
alpha <- {alpha}
metrics <- c({metrics})
tests <- c({tests})        # planned omnibus test per metric (rm_anova or friedman)
posthoc <- "{posthoc}"; adjust <- "{adjust}"; model <- "{model}"
gate <- "{gate}"           # which p of the ANOVA decides (auto: GG when Mauchly p < .05)
gated <- {gated}           # posthoc_gate {posthoc_gate}: the pairs wait for the omnibus test
wilcoxon_gated <- {wilcoxon_gated}  # the same for Friedman's Wilcoxon-Holm pairs
trials <- read.csv("tables/trials.csv", stringsAsFactors = FALSE)
trials$mode <- factor(trials$mode, levels = c({modes}))
trials$position <- trials$position + 1

for (m in metrics) {{
  d <- data.frame(participant = trials$participant, mode = trials$mode,
                  position = trials$position, y = as.numeric(trials[[m]]))
  d <- d[!is.na(d$y), ]
  cat("\\n=====", m, "(planned:", tests[[m]], ")\\n")
  complete <- names(which(table(d$participant) == nlevels(droplevels(d$mode))))
  w <- droplevels(d[d$participant %in% complete, ])
  a <- aov_ez("participant", "y", w, within = "mode",
              anova_table = list(correction = "GG", es = c("pes", "ges")))
  print(summary(a))                       # Mauchly, Greenhouse-Geisser, eta squared
  sph <- summary(a)$sphericity.tests
  violated <- length(sph) > 0 && sph[1, "p-value"] < 0.05
  use_gg <- gate == "greenhouse_geisser" || (gate == "auto" && violated)
  p_gate <- anova(a, correction = if (use_gg) "GG" else "none")[["Pr(>F)"]][1]
  if (!gated || p_gate < alpha) {{
    cat("post hoc", posthoc, "ran (gated p", format(p_gate), ")\n")
    print(summary(pairs(emmeans(a, ~ mode, model = model), adjust = adjust),
                  infer = c(TRUE, TRUE), level = 1 - alpha))
  }} else cat("post hoc", posthoc, "not run: gated p", format(p_gate), ">= alpha\n")
  wide <- reshape(w[, c("participant", "mode", "y")], idvar = "participant",
                  timevar = "mode", direction = "wide")
  ft <- friedman.test(as.matrix(wide[, -1]))
  print(ft)
  if (!wilcoxon_gated || ft$p.value < alpha) {{
    print(pairwise.wilcox.test(w$y, w$mode, paired = TRUE, p.adjust.method = "holm",
                               exact = FALSE))
  }} else cat("Wilcoxon pairs not run: Friedman p >= alpha\n")
  full <- lmer(y ~ mode + position + (1 | participant), data = d, REML = FALSE)
  null <- lmer(y ~ position + (1 | participant), data = d, REML = FALSE)
  print(anova(null, full))                # likelihood-ratio test of mode (ML fits)
}}
"""


def _r_strings(values: list[str]) -> str:
    return ", ".join('"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"' for v in values)


def analysis_r(
    *,
    name: str,
    sha: str,
    alpha: float,
    metrics: list[str],
    tests: dict[str, str],
    posthoc: str,
    modes: list[str],
    gate: str = "auto",
    posthoc_gate: str = "auto",
) -> str:
    """The text of ``analysis.R`` for the planned ``metrics`` (columns of trials.csv),
    their planned ``tests`` (metric -> ``"rm_anova"`` or ``"friedman"``), the post-hoc
    family and the modes in the study's order; ``gate`` and ``posthoc_gate`` as
    :func:`analysis.stats.analyse` (the post-hoc pairs behind the omnibus test or not)."""
    gated = posthoc_gate == "omnibus" or (posthoc_gate == "auto" and posthoc.startswith("lsd"))
    named = ", ".join(f"{m} = {_r_strings([tests[m]])}" for m in metrics)
    return _TEMPLATE.format(
        name=name.replace("\n", " "),
        sha=sha,
        alpha=repr(float(alpha)),
        metrics=_r_strings(metrics),
        tests=named,
        posthoc=posthoc,
        adjust=_ADJUST[posthoc],
        model="univariate" if posthoc == "lsd_pooled" else "multivariate",
        modes=_r_strings(modes),
        gate=gate,
        gated="TRUE" if gated else "FALSE",
        posthoc_gate=posthoc_gate,
        wilcoxon_gated="TRUE" if posthoc_gate == "omnibus" else "FALSE",
    )


__all__ = ["analysis_r"]
