"""Which estimator recovers most of what could be known? Each estimator's within-frame ranking against the
twin's strike oracle (and the error), with paired bootstrap intervals over the test hits, beside its
intervals' coverage and width, and the sentence the report states, generated from those numbers.

The bars (the uncertainty issue's, made explicit):
- recovers the oracle: mean within-frame Spearman with the oracle std over frames 1-20 >= ORACLE_BAR;
- nominal coverage: pooled test coverage within COVERAGE_SLACK of the nominal;
- conditional coverage: coverage >= MIN_TERCILE_COVERAGE in each tercile of the interval width;
- narrower: mean width at most NARROWER times plain conformal's.
Hits are resampled whole (their frames together), the same resamples for every estimator. Without an oracle
(a lab run) the ranking is judged against the error alone and the oracle columns are NaN.
"""

import numpy as np
import pandas as pd
from scipy import stats

from pingpong.curation.schemas import HIT_KEYS
from pingpong.reports.uncertainty import ORACLE_FRAMES

ORACLE_BAR = 0.6
COVERAGE_SLACK = 0.03  # "pooled coverage within 3 points"
MIN_TERCILE_COVERAGE = 0.85
NARROWER = 0.7  # "mean 90 % width at most 0.7 of plain conformal's"
PAPER_BASELINES = ("ensemble", "knn")  # the paper's estimators that rank within a frame
N_BOOTSTRAP = 500
LATE_FRAMES = 10  # the last 100 ms before the hit, where the paddle already shows the shot


def hit_frame_matrix(table: pd.DataFrame, column: str, frames=None) -> np.ndarray:
    """(test hits, frames) values of `column` on the test part, hits in sorted key order; frames: the
    frames before the hit to keep (None: all)."""
    t = table[table["split"] == "test"]
    if frames is not None:
        t = t[t["frames_before_hit"].isin(frames)]
    return t.pivot(index=HIT_KEYS, columns="frames_before_hit", values=column).to_numpy(float)


def _row_spearman(u: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Spearman per row of (B, n) arrays; 0 where u is constant (no ranking)."""
    ru, re = stats.rankdata(u, axis=1), stats.rankdata(e, axis=1)
    ru, re = ru - ru.mean(1, keepdims=True), re - re.mean(1, keepdims=True)
    norm = np.sqrt((ru**2).sum(1) * (re**2).sum(1))
    return np.divide((ru * re).sum(1), norm, out=np.zeros(len(u)), where=norm > 0)


def bootstrap_within_frame(U: np.ndarray, E: np.ndarray, resamples: np.ndarray) -> np.ndarray:
    """Within-frame Spearman (mean over frames) of uncertainty U against a target E (hits, frames: the
    error or the oracle std), for each row of hit indices in resamples (B, hits); row 0 should be the
    identity."""
    return np.mean([_row_spearman(U[resamples, f], E[resamples, f]) for f in range(U.shape[1])], axis=0)


def _interval(boot: np.ndarray) -> tuple[float, float]:
    """The 95 % percentile interval of a statistic's bootstrap resamples (row 0, the data, left out)."""
    return float(np.percentile(boot[1:], 2.5)), float(np.percentile(boot[1:], 97.5))


def _with_interval(column: str, prefix: str, boot: np.ndarray) -> dict:
    """{column: the statistic, prefix_low95, prefix_high95: its bootstrap interval}."""
    low, high = _interval(boot)
    return {column: boot[0], f"{prefix}_low95": low, f"{prefix}_high95": high}


def verdict_table(tables: dict[str, pd.DataFrame], summary: pd.DataFrame, coverage: float,
                  rng: np.random.Generator, n_bootstrap: int = N_BOOTSTRAP) -> pd.DataFrame:
    """One row per estimator: its within-frame Spearman with the oracle std over frames 1-20 and with the
    error over every frame (95 % intervals), its gain over the paper's best ranking (paired), its
    intervals (reports.uncertainty.summary_table's) and the bars met. tables: with_oracle's, estimators
    only."""
    first = next(iter(tables.values()))
    oracle = hit_frame_matrix(first, "oracle_std", ORACLE_FRAMES)
    keep = np.isfinite(oracle).all(axis=1)  # the test hits with an oracle std at every frame 1-20
    oracle, n = oracle[keep], int(keep.sum())
    resamples = np.vstack([np.arange(n), rng.integers(0, n, size=(n_bootstrap, n))]) if n else None
    E_all = hit_frame_matrix(first, "abs_error")
    resamples_all = np.vstack([np.arange(len(E_all)), rng.integers(0, len(E_all), (n_bootstrap, len(E_all)))])
    boot = {name: (bootstrap_within_frame(hit_frame_matrix(t, "uncertainty", ORACLE_FRAMES)[keep], oracle,
                                          resamples) if n else np.full(n_bootstrap + 1, np.nan),
                   bootstrap_within_frame(hit_frame_matrix(t, "uncertainty"), E_all, resamples_all))
            for name, t in tables.items()}
    paper = max((b for b in PAPER_BASELINES if b in boot), key=lambda b: boot[b][0][0], default=None)
    by_name = summary.set_index("estimator")
    conformal_width = by_name.loc["conformal", "mean_width_cm"]
    rows = []
    for name, (rho_oracle, rho_error) in boot.items():
        s = by_name.loc[name]
        gain = rho_oracle - boot[paper][0] if paper else np.full_like(rho_oracle, np.nan)
        row = {"estimator": name, **_with_interval("spearman_oracle_1_20", "oracle", rho_oracle),
               **_with_interval("gain_over_paper", "gain", gain),
               **_with_interval("spearman_error", "error", rho_error),
               "coverage": s["coverage"], "coverage_min_width_tercile": s["coverage_min_width_tercile"],
               "mean_width_cm": s["mean_width_cm"],
               "width_vs_conformal": s["mean_width_cm"] / conformal_width}
        row |= {"recovers_oracle": bool(row["spearman_oracle_1_20"] >= ORACLE_BAR),
                "nominal_coverage": bool(abs(row["coverage"] - coverage) <= COVERAGE_SLACK),
                "conditional_coverage": bool(row["coverage_min_width_tercile"] >= MIN_TERCILE_COVERAGE),
                "narrower": bool(row["width_vs_conformal"] <= NARROWER)}
        row["meets_all"] = all(row[k] for k in ("recovers_oracle", "nominal_coverage", "conditional_coverage",
                                                "narrower"))
        rows.append(row)
    return pd.DataFrame(rows).assign(paper_baseline=paper, n_oracle_hits=n)


def _best(verdict: pd.DataFrame, column: str) -> pd.Series:
    ranked = verdict.dropna(subset=[column])
    return ranked.sort_values(column).iloc[-1] if len(ranked) else verdict.iloc[0]


def verdict_text(verdict: pd.DataFrame, summary: pd.DataFrame, diagnostics: dict, coverage: float) -> str:
    """The report's answer, from the numbers: which estimator recovers most of the oracle (or, without
    one, ranks the errors best), at what coverage and width, which meet every bar, and why the rest fall
    short (the diagnostics fit_uncertainty wrote)."""
    base = summary.set_index("estimator")
    has_oracle = verdict["spearman_oracle_1_20"].notna().any()
    column = "spearman_oracle_1_20" if has_oracle else "spearman_error"
    best = _best(verdict, column)
    winners = verdict.loc[verdict["meets_all"], "estimator"].tolist()
    lines = [f"**Verdict: {', '.join(winners)} meet every bar.**" if winners
             else "**Verdict: no estimator meets every bar on these data.**"]
    target = "the oracle std over frames 1-20" if has_oracle else "the absolute error"
    low, high = (best["oracle_low95"], best["oracle_high95"]) if has_oracle else (best["error_low95"],
                                                                                 best["error_high95"])
    line = (f"Most of what could be known: {best['estimator']}, within-frame Spearman with {target} "
            f"{best[column]:.2f} (95 % {low:.2f} to {high:.2f})")
    if has_oracle:
        line += (f", {best['gain_over_paper']:+.2f} over the paper's best ({best['paper_baseline']}; "
                 f"95 % {best['gain_low95']:+.2f} to {best['gain_high95']:+.2f}, "
                 f"{int(best['n_oracle_hits'])} hits)")
    lines.append(line + f"; its intervals cover {best['coverage']:.3f} "
                 f"({best['coverage_min_width_tercile']:.3f} in the worst width tercile) at "
                 f"{best['mean_width_cm']:.0f} cm mean width, "
                 f"{best['width_vs_conformal']:.2f} of plain conformal's "
                 f"{base.loc['conformal', 'mean_width_cm']:.0f} cm.")
    if "oracle" in base.index:
        lines.append(f"The ceiling: the oracle's own std ranks the model's errors at within-frame Spearman "
                     f"{base.loc['oracle', 'spearman_within_frame']:.2f} (the best any estimator's "
                     f"{verdict['spearman_error'].max():.2f}); what is left is the model's misfit.")
    covered = verdict[verdict["nominal_coverage"] & verdict["conditional_coverage"]]
    if len(covered):
        narrowest = covered.sort_values("mean_width_cm").iloc[0]
        lines.append(f"Narrowest intervals at nominal and conditional coverage: {narrowest['estimator']}, "
                     f"{narrowest['mean_width_cm']:.0f} cm (coverage {narrowest['coverage']:.3f}).")
    agreement = diagnostics.get("member_error_spearman_within_frame")
    if agreement is not None:
        lines.append(f"Why the ensemble sees little: its members err on the same hits (within-frame Spearman "
                     f"between two members' absolute errors {agreement:.2f}).")
    return "\n\n".join(lines)


def window_text(by_frame: pd.DataFrame) -> str:
    """Where in the approach ranking works: the best mean within-frame Spearman (reports.uncertainty's
    by_frame_table) over the last LATE_FRAMES frames, and over the frames before them."""
    rho = by_frame.dropna(subset=["spearman"])
    late = rho["frames_before_hit"] <= LATE_FRAMES
    parts = []
    for label, part in ((f"the last {LATE_FRAMES} frames before the hit and the hit itself", rho[late]),
                        ("the frames before those", rho[~late])):
        mean = part.groupby("estimator")["spearman"].mean()
        # a within-frame Spearman needs a few test hits; with too few every frame's is undefined
        best = f"{mean.max():.2f} ({mean.idxmax()})" if len(mean) else "undefined"
        parts.append(f"{best} over {label}")
    return "Where: the best mean within-frame Spearman with the error is " + "; ".join(parts) + "."
