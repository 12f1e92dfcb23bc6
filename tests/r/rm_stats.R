#!/usr/bin/env Rscript
# Reference computation, in base R, of what `asa stats` reports (analysis/stats/).
# (The thesis's chain only; tests/r/oracle.R is the full oracle of issue 21, with golden files.)
#
# It produced nothing stored in this repository by itself: R is not installed on the machine
# where the tests were written, so the tests check analysis/stats/ against independent
# Python computations (explicit loops, statsmodels' AnovaRM, scipy's ttest_rel, R's
# mauchly.test algorithm transcribed into the test, pingouin) and against the published SPSS
# output of Field's "Bushtucker" example (Field, A., Discovering Statistics Using SPSS,
# repeated-measures chapter): W = .136, chi2(5) = 11.41, p = .047, GG eps = .533,
# HF eps = .666, F(3, 21) = 3.79, p = .026, GG p = .063 -- the data are bushtucker.csv here.
# Run this script to reproduce those numbers (and the LSD pairs) from R:
#
#   Rscript tests/r/rm_stats.R                       # bushtucker.csv retch_s animal celebrity
#   Rscript tests/r/rm_stats.R FILE DV WITHIN SUBJECT
#
# and compare with `asa stats --csv FILE --dv DV --within WITHIN --subject SUBJECT --json`.

args <- commandArgs(trailingOnly = TRUE)
if (length(args) == 0) {
  script <- sub("^--file=", "", grep("^--file=", commandArgs(FALSE), value = TRUE))
  args <- c(file.path(dirname(script), "bushtucker.csv"), "retch_s", "animal", "celebrity")
}
stopifnot(length(args) == 4)
d <- read.csv(args[1], colClasses = "character", strip.white = TRUE)
dv <- args[2]; within <- args[3]; subject <- args[4]
d[[dv]] <- as.numeric(d[[dv]])
levels <- unique(d[[within]])          # first-appearance order, as asa stats
subjects <- unique(d[[subject]])

# Cell means (duplicates averaged), wide table, listwise deletion.
cell <- aggregate(d[[dv]], by = list(s = d[[subject]], w = d[[within]]), FUN = mean)
wide <- matrix(NA_real_, length(subjects), length(levels), dimnames = list(subjects, levels))
wide[cbind(match(cell$s, subjects), match(cell$w, levels))] <- cell$x
cat("dropped_subjects:", rownames(wide)[!complete.cases(wide)], "\n")
wide <- wide[complete.cases(wide), , drop = FALSE]
n <- nrow(wide); k <- ncol(wide)
cat("n_subjects:", n, "\n")

# Descriptives
for (j in seq_len(k)) {
  x <- wide[, j]
  cat(sprintf("descriptives %s: mean %.10g sd %.10g se %.10g n %d\n",
              levels[j], mean(x), sd(x), sd(x) / sqrt(n), n))
}

# One-way repeated-measures ANOVA (univariate, sphericity assumed)
long <- data.frame(y = as.vector(wide),
                   s = factor(rep(rownames(wide), times = k)),
                   w = factor(rep(levels, each = n), levels = levels))
fit <- summary(aov(y ~ w + Error(s / w), data = long))
tab <- fit[["Error: s:w"]][[1]]
F <- tab[1, "F value"]; df1 <- tab[1, "Df"]; df2 <- tab[2, "Df"]
ss_effect <- tab[1, "Sum Sq"]; ss_error <- tab[2, "Sum Sq"]
ss_subjects <- fit[["Error: s"]][[1]][1, "Sum Sq"]
cat(sprintf("anova: F %.10g df_effect %d df_error %d p_unc %.10g\n", F, df1, df2,
            tab[1, "Pr(>F)"]))
cat(sprintf("anova: ss_effect %.10g ss_error %.10g ms_error %.10g\n",
            ss_effect, ss_error, ss_error / df2))
cat(sprintf("anova: np2 %.10g ng2 %.10g\n", ss_effect / (ss_effect + ss_error),
            ss_effect / (ss_effect + ss_subjects + ss_error)))

# Mauchly's test exactly as R computes it; R prints W and p only, so chi2 (R's internal z)
# is recomputed with the same formula.
mlm <- lm(wide ~ 1)
mt <- mauchly.test(mlm, X = ~1)
pp <- k - 1; nu <- n - 1
rho <- 1 - (2 * pp^2 + pp + 2) / (6 * pp * nu)
z <- -nu * rho * log(mt$statistic)
cat(sprintf("sphericity: W %.10g chi2 %.10g dof %d p %.10g\n",
            mt$statistic, z, pp * (pp + 1) / 2 - 1, mt$p.value))

# Greenhouse-Geisser epsilon (Box) on the double-centred covariance, corrected p
S <- cov(wide); H <- diag(k) - matrix(1 / k, k, k); Sdc <- H %*% S %*% H
eps <- sum(diag(Sdc))^2 / ((k - 1) * sum(Sdc * Sdc))
cat(sprintf("greenhouse_geisser: eps %.10g p %.10g\n", eps,
            pf(F, eps * df1, eps * df2, lower.tail = FALSE)))

# Fisher's LSD: paired (SPSS "compare main effects", LSD) and pooled (MS_error, df_error)
ms_error <- ss_error / df2
for (a in 1:(k - 1)) for (b in (a + 1):k) {
  tt <- t.test(wide[, a], wide[, b], paired = TRUE, conf.level = 0.95)
  cat(sprintf("lsd_paired %s - %s: diff %.10g t %.10g df %d p %.10g ci %.10g %.10g\n",
              levels[a], levels[b], tt$estimate, tt$statistic, tt$parameter, tt$p.value,
              tt$conf.int[1], tt$conf.int[2]))
  diff <- mean(wide[, a]) - mean(wide[, b]); se <- sqrt(2 * ms_error / n)
  t <- diff / se; q <- qt(0.975, df2)
  cat(sprintf("lsd_pooled %s - %s: diff %.10g t %.10g df %d p %.10g ci %.10g %.10g\n",
              levels[a], levels[b], diff, t, df2, 2 * pt(-abs(t), df2),
              diff - q * se, diff + q * se))
}
