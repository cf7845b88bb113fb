"""Split conformal quantiles that calibrate by hit, never by frame.

The 31 frames of one hit are strongly dependent, so a hit, not a frame, is the exchangeable unit.
`conformal_quantile` gives every calibration hit a total weight of 1 spread over its scores and adds
the unseen test hit as weight 1 at +inf. With F_i the empirical CDF of hit i's scores, the
returned q is the smallest score with sum_{i<=n} F_i(q) >= (1 - alpha)(n + 1). Since the test hit's
F_{n+1} <= 1, q is at least the symmetric q* = min{s: sum_{i<=n+1} F_i(s) >= (1 - alpha)(n + 1)},
and by exchangeability of hits E[F_{n+1}(q)] >= E[F_{n+1}(q*)] = E[mean_i F_i(q*)] >= 1 - alpha:
the share of a test hit's frames covered is >= 1 - alpha on average. With one score per hit this is
the usual ceil((1 - alpha)(n + 1))-th smallest score, and coverage <= 1 - alpha + 1/(n + 1) when
scores have no ties.
"""

import numpy as np


def conformal_quantile(scores, alpha: float, groups=None) -> float:
    """The hit-weighted conformal quantile of `scores` (module doc); +inf when too few hits for 1 - alpha.

    groups: the hit of each score (None: every score its own hit).
    """
    scores = np.asarray(scores, dtype=float)
    if not 0 < alpha < 1:
        raise ValueError(f"conformal_quantile: alpha {alpha} must lie in (0, 1)")
    if scores.size == 0 or not np.isfinite(scores).all():
        raise ValueError(f"conformal_quantile: need finite scores, got {scores.size} with "
                         f"{int((~np.isfinite(scores)).sum())} non-finite")
    if groups is None:
        groups = np.arange(scores.size)
    _, hit, per_hit = np.unique(np.asarray(groups), return_inverse=True, return_counts=True)
    n_hits = per_hit.size
    order = np.argsort(scores, kind="stable")
    mass = np.cumsum(1.0 / per_hit[hit[order]])
    need = (1 - alpha) * (n_hits + 1)
    reached = np.nonzero(mass >= need - 1e-9 * n_hits)[0]  # tolerance: the sum of 1/K_i rounds
    return float(scores[order[reached[0]]]) if reached.size else float("inf")


def mondrian_quantiles(scores, strata, alpha: float, groups=None) -> dict:
    """`conformal_quantile` within each stratum (here: frame before the hit): stratum -> quantile."""
    scores, strata = np.asarray(scores, dtype=float), np.asarray(strata)
    groups = np.arange(scores.size) if groups is None else np.asarray(groups)
    return {s.item(): conformal_quantile(scores[strata == s], alpha, groups[strata == s])
            for s in np.unique(strata)}


def normalised_scores(abs_errors, difficulty) -> np.ndarray:
    """Scores |y - y_hat| / sigma of normalised conformal; the interval is y_hat +- q * sigma."""
    return np.asarray(abs_errors, dtype=float) / np.asarray(difficulty, dtype=float)


def cqr_scores(y, lower, upper) -> np.ndarray:
    """Scores of conformalised quantile regression: how far y lies outside [lower, upper] (< 0 inside).

    The conformal interval is [lower - q, upper + q] (Romano et al. 2019).
    """
    y = np.asarray(y, dtype=float)
    return np.maximum(np.asarray(lower) - y, y - np.asarray(upper))
