#!/usr/bin/env Rscript
# The R oracle of `asa stats` (issue 21): every figure of analysis/stats/ recomputed in R from
# a long CSV, written as a golden JSON file beside this script (tests/r/golden/NAME.json).
# tests/test_stats_oracle.py compares `asa stats --json` with them (1e-6; mixed models 1e-3).
#
#   Rscript tests/r/oracle.R                 # every dataset of tests/r/datasets.json
#   Rscript tests/r/oracle.R OUT_DIR [NAME]  # write elsewhere (the slow test), or one dataset
#
# Needs R >= 4.2 with afex, emmeans, lme4, jsonlite (Debian: r-base-core r-cran-afex
# r-cran-emmeans r-cran-lme4 r-cran-lmertest r-cran-jsonlite). The datasets come from
# tests/r/make_datasets.py (seeded) and Field's Bushtucker data.
# Settings as `asa stats` defaults: alpha = .05, gate auto (Greenhouse-Geisser p when
# Mauchly's p < .05), posthoc_gate auto (LSD behind the gate; Holm, Bonferroni and the
# Wilcoxon-Holm pairs always), eta squared CI 1 - 2 alpha, pair CIs 1 - alpha.

suppressPackageStartupMessages({
  library(afex); library(emmeans); library(lme4); library(jsonlite)
})
afex_options(emmeans_model = "multivariate")

args <- commandArgs(trailingOnly = TRUE)
script <- sub("^--file=", "", grep("^--file=", commandArgs(FALSE), value = TRUE))
here <- normalizePath(dirname(script))
out_dir <- if (length(args) >= 1) args[1] else file.path(here, "golden")
manifest <- fromJSON(file.path(here, "datasets.json"), simplifyVector = FALSE)
if (length(args) >= 2) manifest <- Filter(function(m) m$name == args[2], manifest)
alpha <- 0.05

pairs_of <- function(k) { p <- combn(k, 2); lapply(seq_len(ncol(p)), function(i) p[, i]) }

read_long <- function(m) {
  d <- read.csv(file.path(here, m$csv), colClasses = "character", strip.white = TRUE)
  data.frame(s = d[[m$subject]], w = d[[m$within]], y = as.numeric(d[[m$dv]]),
             pos = if (is.null(m$order)) NA_real_ else as.numeric(d[[m$order]]),
             stringsAsFactors = FALSE)
}

wide_of <- function(d, levels) {
  d <- d[!is.na(d$y), ]
  subjects <- unique(d$s)
  cell <- aggregate(y ~ s + w, d, mean)
  wide <- matrix(NA_real_, length(subjects), length(levels), dimnames = list(subjects, levels))
  wide[cbind(match(cell$s, subjects), match(cell$w, levels))] <- cell$y
  wide[complete.cases(wide), , drop = FALSE]
}

ncp_f <- function(F, df1, df2, level) {   # noncentral-F interval of lambda (Steiger 2004)
  b <- function(target) {
    if (pf(F, df1, df2) <= target) return(0)
    uniroot(function(l) pf(F, df1, df2, ncp = l) - target, c(0, max(10, 10 * F * df1)),
            extendInt = "downX", tol = 1e-13)$root
  }
  c(b((1 + level) / 2), b((1 - level) / 2))
}

ncp_t <- function(t, df, level) {          # noncentral-t interval of delta
  b <- function(target) uniroot(function(d) pt(t, df, ncp = d) - target,
                                c(t - 10 * (1 + abs(t)), t + 10 * (1 + abs(t))),
                                extendInt = "downX", tol = 1e-13)$root
  c(b((1 + level) / 2), b((1 - level) / 2))
}

omnibus <- function(wide, levels) {
  n <- nrow(wide); k <- ncol(wide)
  long <- data.frame(y = as.vector(wide), s = factor(rep(rownames(wide), times = k)),
                     w = factor(rep(levels, each = n), levels = levels))
  a <- aov_ez("s", "y", long, within = "w",
              anova_table = list(correction = "none", es = c("pes", "ges")), include_aov = TRUE)
  tab <- a$anova_table
  fit <- summary(aov(y ~ w + Error(s / w), data = long))
  ss <- fit[["Error: s:w"]][[1]]
  anova <- list(F = tab$F, df_effect = tab$`num Df`, df_error = tab$`den Df`, p_unc = tab$`Pr(>F)`,
                ss_effect = ss[1, "Sum Sq"], ss_error = ss[2, "Sum Sq"],
                ms_error = ss[2, "Sum Sq"] / ss[2, "Df"], np2 = tab$pes, ng2 = tab$ges)
  gg <- summary(a)$pval.adjustments
  sph <- list(W = 1, chi2 = 0, dof = 0L, p = 1)
  eps <- 1; p_gg <- tab$`Pr(>F)`
  if (k > 2) {
    mt <- mauchly.test(lm(wide ~ 1), X = ~1)
    pp <- k - 1; nu <- n - 1; rho <- 1 - (2 * pp^2 + pp + 2) / (6 * pp * nu)
    sph <- list(W = unname(mt$statistic), chi2 = unname(-nu * rho * log(mt$statistic)),
                dof = as.integer(pp * (pp + 1) / 2 - 1), p = mt$p.value)
    eps <- unname(gg[1, "GG eps"]); p_gg <- unname(gg[1, "Pr(>F[GG])"])
  }
  sph$violated <- sph$p < alpha
  lam <- ncp_f(tab$F, tab$`num Df`, tab$`den Df`, 1 - 2 * alpha)
  d12 <- tab$`num Df` + tab$`den Df` + 1
  list(a = a, anova = anova, sphericity = sph, greenhouse_geisser = list(eps = eps, p = p_gg),
       np2 = list(value = tab$pes, ci_low = lam[1] / (lam[1] + d12),
                  ci_high = lam[2] / (lam[2] + d12)))
}

pair_rows <- function(wide, levels) lapply(pairs_of(ncol(wide)), function(ij) {
  x <- wide[, ij[1]]; y <- wide[, ij[2]]; n <- length(x); d <- x - y
  tt <- t.test(x, y, paired = TRUE, conf.level = 1 - alpha)
  dz <- mean(d) / sd(d); del <- ncp_t(dz * sqrt(n), n - 1, 1 - alpha)
  sw <- shapiro.test(d)
  list(effect = list(a = levels[ij[1]], b = levels[ij[2]], n = n, diff = mean(d), sd_diff = sd(d),
                     ci_low = tt$conf.int[1], ci_high = tt$conf.int[2], dz = dz,
                     dz_ci_low = del[1] / sqrt(n), dz_ci_high = del[2] / sqrt(n)),
       normal = list(a = levels[ij[1]], b = levels[ij[2]], W = unname(sw$statistic),
                     p = sw$p.value, violated = sw$p.value < alpha))
})

# emmeans pairs of the afex fit: multivariate model = paired t per pair; univariate = pooled.
family <- function(a, model, adjust) {
  em <- emmeans(a, ~ w, model = model)
  pr <- pairs(em, adjust = adjust)
  s <- summary(pr, infer = c(TRUE, TRUE), adjust = adjust, level = 1 - alpha)
  raw <- summary(pairs(em, adjust = "none"), infer = c(TRUE, TRUE))
  rows <- lapply(seq_len(nrow(s)), function(i) {
    ab <- strsplit(as.character(s$contrast[i]), " - ", fixed = TRUE)[[1]]
    r <- list(a = ab[1], b = ab[2], diff = s$estimate[i], t = s$t.ratio[i], df = s$df[i],
              p = s$p.value[i], ci_low = s$lower.CL[i], ci_high = s$upper.CL[i],
              significant = s$p.value[i] < alpha)
    if (adjust != "none") r$p_unc <- raw$p.value[i]
    r
  })
  rows
}

wilcoxon_holm <- function(wide, levels) {
  rows <- lapply(pairs_of(ncol(wide)), function(ij) {
    d <- wide[, ij[1]] - wide[, ij[2]]
    w <- suppressWarnings(wilcox.test(wide[, ij[1]], wide[, ij[2]], paired = TRUE))
    list(a = levels[ij[1]], b = levels[ij[2]], median_diff = median(d),
         V = unname(w$statistic), n = sum(d != 0), p_unc = w$p.value)
  })
  adj <- p.adjust(sapply(rows, `[[`, "p_unc"), "holm")
  for (i in seq_along(rows)) { rows[[i]]$p <- adj[i]; rows[[i]]$significant <- adj[i] < alpha }
  rows
}

nonparametric <- function(wide, levels) {
  ft <- friedman.test(wide)
  n <- nrow(wide); k <- ncol(wide); chi2 <- unname(ft$statistic)
  out <- list(chi2 = chi2, df = k - 1, p = ft$p.value, kendall_w = chi2 / (n * (k - 1)), n = n,
              significant = ft$p.value < alpha)
  # posthoc_gate "auto": Holm controls the family-wise error on its own, so the Wilcoxon
  # pairs do not wait for Friedman's test (docs/decisions.md, "Post-hoc gate")
  out$posthoc <- list(ran = TRUE, gated = FALSE, wilcoxon_holm = wilcoxon_holm(wide, levels))
  out
}

mixed_models <- function(d, levels) {
  d <- d[!is.na(d$y), ]
  d <- aggregate(cbind(y, pos) ~ s + w, d, mean, na.action = na.pass)
  d$mode <- factor(d$w, levels = levels); d$s <- factor(d$s)
  has_pos <- !all(is.na(d$pos))
  full <- if (has_pos) y ~ mode + pos + (1 | s) else y ~ mode + (1 | s)
  reduced <- if (has_pos) y ~ pos + (1 | s) else y ~ 1 + (1 | s)
  lrt <- function(f1, f0) {
    m1 <- lmer(f1, d, REML = FALSE); m0 <- lmer(f0, d, REML = FALSE)
    l1 <- as.numeric(logLik(m1)); l0 <- as.numeric(logLik(m0))
    df <- attr(logLik(m1), "df") - attr(logLik(m0), "df"); chi2 <- max(0, 2 * (l1 - l0))
    list(chi2 = chi2, df = df, p = pchisq(chi2, df, lower.tail = FALSE),
         loglik_full = l1, loglik_reduced = l0, significant = pchisq(chi2, df, lower.tail = FALSE) < alpha)
  }
  reml <- lmer(full, d)
  co <- summary(reml)$coefficients
  terms <- sub("^pos$", "position", rownames(co))
  vc <- as.data.frame(VarCorr(reml))
  per <- table(d$s)
  mixed <- list(n_obs = nrow(d), n_subjects = length(per),
                incomplete_subjects = as.list(names(per)[per < length(levels)]),
                lrt = lrt(full, reduced),
                fixed = lapply(seq_len(nrow(co)), function(i)
                  list(term = terms[i], estimate = co[i, 1], se = co[i, 2])),
                var_subject = vc$vcov[1], var_residual = vc$vcov[2])
  order <- NULL
  if (has_pos) {
    d$pf <- factor(d$pos)
    means <- tapply(d$y, d$pf, mean)
    order <- list(position = lrt(y ~ mode + pf + (1 | s), y ~ mode + (1 | s)),
                  mode_x_position = lrt(y ~ mode * pf + (1 | s), y ~ mode + pf + (1 | s)),
                  position_means = as.list(means))
  }
  list(mixed = mixed, order = order)
}

golden <- function(m) {
  d <- read_long(m)
  levels <- unique(d$w)                    # first appearance, as asa stats
  wide <- wide_of(d, levels)
  n <- nrow(wide)
  o <- omnibus(wide, levels)
  p_gate <- if (o$sphericity$violated) o$greenhouse_geisser$p else o$anova$p_unc
  significant <- p_gate < alpha
  pr <- pair_rows(wide, levels)
  rst <- rstudent(lm(y ~ s + w, data.frame(y = as.vector(wide),
                                           s = factor(rep(rownames(wide), ncol(wide))),
                                           w = factor(rep(levels, each = n)))))
  none <- list()
  # posthoc_gate "auto": Fisher's LSD only behind the gate; Holm and Bonferroni always
  posthoc <- list(ran = significant, gated = TRUE, posthoc_gate = "auto",
    lsd_paired = if (significant) family(o$a, "multivariate", "none") else none,
    lsd_pooled = if (significant) family(o$a, "univariate", "none") else none,
    holm = family(o$a, "multivariate", "holm"),
    bonferroni = family(o$a, "multivariate", "bonferroni"))
  mm <- mixed_models(d, levels)
  pkgs <- c("afex", "emmeans", "lme4", "jsonlite")
  out <- list(
    `_meta` = list(dataset = m$name, csv = m$csv, dv = m$dv, within = m$within,
                   subject = m$subject, order = m$order, alpha = alpha,
                   R = R.version.string,
                   packages = setNames(lapply(pkgs, function(p) as.character(packageVersion(p))), pkgs),
                   script = "tests/r/oracle.R"),
    n_subjects = n, levels = as.list(levels),
    descriptives = setNames(lapply(seq_along(levels), function(j)
      list(mean = mean(wide[, j]), sd = sd(wide[, j]), se = sd(wide[, j]) / sqrt(n), n = n)), levels),
    anova = o$anova, sphericity = o$sphericity, greenhouse_geisser = o$greenhouse_geisser,
    p_gate = p_gate, significant = significant, posthoc = posthoc,
    effect_sizes = list(np2 = o$np2),
    pairs = lapply(pr, `[[`, "effect"),
    assumptions = list(normality = list(pairs = lapply(pr, `[[`, "normal")),
                       outliers = list(max_abs = max(abs(rst)), count = sum(abs(rst) > 3))),
    friedman = nonparametric(wide, levels),
    mixed = mm$mixed)
  if (!is.null(mm$order)) out$order <- mm$order
  out
}

dir.create(out_dir, showWarnings = FALSE, recursive = TRUE)
for (m in manifest) {
  g <- golden(m)
  writeLines(toJSON(g, auto_unbox = TRUE, digits = NA, null = "null", pretty = TRUE),
             file.path(out_dir, paste0(m$name, ".json")))
  cat("wrote", file.path(out_dir, paste0(m$name, ".json")), "\n")
}
