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
  print(summary(pairs(emmeans(a, ~ mode, model = model), adjust = adjust),
                infer = c(TRUE, TRUE), level = 1 - alpha))
  wide <- reshape(w[, c("participant", "mode", "y")], idvar = "participant",
                  timevar = "mode", direction = "wide")
  print(friedman.test(as.matrix(wide[, -1])))
  print(pairwise.wilcox.test(w$y, w$mode, paired = TRUE, p.adjust.method = "holm",
                             exact = FALSE))
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
) -> str:
    """The text of ``analysis.R`` for the planned ``metrics`` (columns of trials.csv),
    their planned ``tests`` (metric -> ``"rm_anova"`` or ``"friedman"``), the post-hoc
    family and the modes in the study's order."""
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
    )


__all__ = ["analysis_r"]
