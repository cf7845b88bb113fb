"""Is an uncertainty informative? Rank correlation with the error, sparsification, interval quality.

Every metric takes per-(hit, frame) arrays of one part (the test part). Pooled over frames an
estimator is rewarded for knowing the time to the hit alone, so each ranking metric also comes
within each frame before the hit, averaged over frames.
"""

import numpy as np
from scipy import stats

FRACTIONS = np.linspace(0.0, 0.95, 20)  # shares of the most uncertain predictions removed


def spearman(uncertainty, abs_errors) -> float:
    """Spearman's rho between uncertainty and absolute error; NaN when either is constant."""
    u, e = np.asarray(uncertainty, float), np.asarray(abs_errors, float)
    if u.size < 3 or np.unique(u).size < 2 or np.unique(e).size < 2:
        return float("nan")
    return float(stats.spearmanr(u, e).statistic)


def within_frames(metric, uncertainty, abs_errors, frames) -> float:
    """Mean over frame indices of `metric(u, e)` computed within each frame (NaN frames skipped)."""
    u, e, frames = (np.asarray(a) for a in (uncertainty, abs_errors, frames))
    values = [metric(u[frames == f], e[frames == f]) for f in np.unique(frames)]
    values = [v for v in values if np.isfinite(v)]
    return float(np.mean(values)) if values else float("nan")


def _kept_mean_error(ranking, abs_errors, fractions) -> np.ndarray:
    """Mean error of the predictions left after removing the `fractions` ranked highest.

    Ties in `ranking` count at their expected value under a random order: each error is replaced
    by the mean error of its tie group before the cumulative sums.
    """
    r, e = np.asarray(ranking, float), np.asarray(abs_errors, float)
    order = np.argsort(r, kind="stable")
    r, e = r[order], e[order]
    _, tie, counts = np.unique(r, return_inverse=True, return_counts=True)
    e = (np.bincount(tie, weights=e) / counts)[tie]
    cumulative = np.concatenate([[0.0], np.cumsum(e)])
    kept = np.maximum(np.round(r.size * (1 - np.asarray(fractions))).astype(int), 1)
    return cumulative[kept] / kept


def sparsification(uncertainty, abs_errors, fractions=FRACTIONS) -> tuple[np.ndarray, np.ndarray]:
    """(curve, oracle): mean error left after removing each fraction of the most uncertain (curve) or
    of the largest errors (oracle), both divided by the mean error of all predictions."""
    e = np.asarray(abs_errors, float)
    scale = e.mean() if e.mean() > 0 else 1.0
    return (_kept_mean_error(uncertainty, e, fractions) / scale, _kept_mean_error(e, e, fractions) / scale)


def ause(uncertainty, abs_errors, fractions=FRACTIONS) -> float:
    """Area between the sparsification curve and the oracle's (>= 0; 0 = ranks like the errors)."""
    curve, oracle = sparsification(uncertainty, abs_errors, fractions)
    return float(np.trapezoid(curve - oracle, fractions))


def interval_metrics(y, lower, upper) -> dict:
    """Coverage of y by [lower, upper], mean width (m) and the widths' coefficient of variation."""
    y, lower, upper = (np.asarray(a, float) for a in (y, lower, upper))
    width = upper - lower
    if np.isnan(width).all():  # the estimator gives no interval
        return {"coverage": float("nan"), "mean_width": float("nan"), "width_cv": float("nan")}
    mean = width.mean()  # +inf where too few calibration hits for the nominal coverage
    return {"coverage": float(np.mean((lower <= y) & (y <= upper))), "mean_width": float(mean),
            "width_cv": float(width.std() / mean) if 0 < mean < np.inf else float("nan")}


def ence(std, residuals, n_bins: int = 10) -> float:
    """Expected normalised calibration error (Levi et al. 2022): rows binned by predicted std into
    `n_bins` equal-count bins; the mean over bins of |RMV - RMSE| / RMV, with RMV the root mean
    predicted variance and RMSE the root mean squared residual of the bin (0: calibrated in every bin)."""
    s, r = np.asarray(std, float), np.asarray(residuals, float)
    if s.size < n_bins or not (np.isfinite(s).all() and (s > 0).all()):
        return float("nan")
    bins = np.array_split(np.argsort(s, kind="stable"), n_bins)
    rmv = np.array([np.sqrt(np.mean(s[b] ** 2)) for b in bins])
    rmse = np.array([np.sqrt(np.mean(r[b] ** 2)) for b in bins])
    return float(np.mean(np.abs(rmv - rmse) / rmv))


def winkler_score(y, lower, upper, alpha: float) -> float:
    """Mean interval (Winkler) score of central (1 - alpha) intervals, m: the width plus 2 / alpha times
    how far y lies outside (Gneiting & Raftery 2007); lower is better, the width alone when all cover."""
    y, lower, upper = (np.asarray(a, float) for a in (y, lower, upper))
    miss = np.maximum(lower - y, 0.0) + np.maximum(y - upper, 0.0)
    return float(np.mean(upper - lower + 2.0 / alpha * miss))


def coverage_by_width(y, lower, upper, n_bins: int = 3) -> np.ndarray:
    """Coverage within each of `n_bins` equal-count bins of the interval width, narrowest first
    (conditional coverage: an adaptive interval must not buy its narrow widths with misses)."""
    y, lower, upper = (np.asarray(a, float) for a in (y, lower, upper))
    covered = (lower <= y) & (y <= upper)
    bins = np.array_split(np.argsort(upper - lower, kind="stable"), n_bins)
    return np.array([covered[b].mean() for b in bins])
