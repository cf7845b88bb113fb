"""The uncertainty report: every estimator's metrics on the test hits, and the paper's figures."""

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from pingpong.common.atomic import atomic_path  # noqa: E402
from pingpong.uncertainty.metrics import (  # noqa: E402
    FRACTIONS,
    ause,
    interval_metrics,
    sparsification,
    spearman,
    within_frames,
)
from pingpong.uncertainty.names import PAPER_ESTIMATORS  # noqa: E402

SCATTER_ESTIMATORS = ("ensemble", "knn", "conformal", "cqr")  # the paper's three, and CQR beside them
LAST_FRAME = 0  # the paper's figure 3a-c: predictions made at t = 0, the hit frame


def _test(table: pd.DataFrame) -> pd.DataFrame:
    return table[table["split"] == "test"]


def summary_table(tables: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """One row per estimator: ranking metrics pooled and within frames, interval metrics (cm)."""
    rows = []
    for name, table in tables.items():
        t = _test(table)
        u, e, f = t["uncertainty"].to_numpy(), t["abs_error"].to_numpy(), t["frames_before_hit"].to_numpy()
        pooled = interval_metrics(t["strike_x"], t["lower"], t["upper"])
        per_frame = [interval_metrics(g["strike_x"], g["lower"], g["upper"])["coverage"]
                     for _, g in t.groupby("frames_before_hit")]
        rows.append({"estimator": name, "paper": name in PAPER_ESTIMATORS,
                     "spearman_pooled": spearman(u, e),
                     "spearman_within_frame": within_frames(spearman, u, e, f),
                     "ause_pooled": ause(u, e), "ause_within_frame": within_frames(ause, u, e, f),
                     "coverage": pooled["coverage"], "coverage_min_frame": np.min(per_frame),
                     "coverage_max_frame": np.max(per_frame), "mean_width_cm": 100 * pooled["mean_width"],
                     "width_cv": pooled["width_cv"], "n_test_hits": t[["session", "rally", "hit"]]
                     .drop_duplicates().shape[0]})
    return pd.DataFrame(rows)


def by_frame_table(tables: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """Per estimator and frame before the hit: Spearman, AUSE, coverage, mean width and median error (cm)."""
    rows = []
    for name, table in tables.items():
        for frame, t in _test(table).groupby("frames_before_hit"):
            u, e = t["uncertainty"].to_numpy(), t["abs_error"].to_numpy()
            interval = interval_metrics(t["strike_x"], t["lower"], t["upper"])
            rows.append({"estimator": name, "frames_before_hit": frame, "spearman": spearman(u, e),
                         "ause": ause(u, e), "coverage": interval["coverage"],
                         "mean_width_cm": 100 * interval["mean_width"],
                         "median_error_cm": 100 * np.median(e)})
    return pd.DataFrame(rows)


def _save(fig, path) -> None:
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=120)
    plt.close(fig)


def plot_error_vs_uncertainty(tables: dict[str, pd.DataFrame], path, frame: int = LAST_FRAME) -> None:
    """The paper's figure: absolute error against uncertainty on the test hits at one frame."""
    names = [n for n in SCATTER_ESTIMATORS if n in tables]
    fig, axes = plt.subplots(1, len(names), figsize=(3.2 * len(names), 3.2), squeeze=False)
    for ax, name in zip(axes[0], names, strict=True):
        t = _test(tables[name])
        t = t[t["frames_before_hit"] == frame]
        ax.scatter(100 * t["uncertainty"], 100 * t["abs_error"], s=10, alpha=0.6)
        if not np.isfinite(t["uncertainty"]).all():
            ax.text(0.5, 0.5, "infinite widths:\ntoo few calibration hits", transform=ax.transAxes,
                    ha="center", va="center")
        ax.set_title(f"{name}: rho = {spearman(t['uncertainty'], t['abs_error']):.2f}", fontsize=9)
        ax.set_xlabel("uncertainty (cm)")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel(f"|error| (cm), {frame} frame(s) before the hit")
    _save(fig, path)


def plot_error_vs_frames(by_frame: pd.DataFrame, time_trend: pd.DataFrame, path) -> None:
    """Median absolute error on the test hits against frames before the hit, with the time-to-hit trend."""
    first = by_frame[by_frame["estimator"] == by_frame["estimator"].iloc[0]]
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(-first["frames_before_hit"], first["median_error_cm"], marker=".", label="median |error| (test)")
    trend = time_trend.drop_duplicates("frames_before_hit").sort_values("frames_before_hit")
    ax.plot(-trend["frames_before_hit"], 100 * trend["uncertainty"], "--",
            label="time-to-hit trend (fit on calibration)")
    ax.set_xlabel("frames before the hit (100 Hz)")
    ax.set_ylabel("strike-point error (cm)")
    ax.legend()
    ax.grid(alpha=0.3)
    _save(fig, path)


def plot_sparsification(tables: dict[str, pd.DataFrame], path) -> None:
    """Pooled sparsification curves of every estimator on the test hits, and the oracle's."""
    fig, ax = plt.subplots(figsize=(6, 4))
    oracle = None
    for name, table in tables.items():
        t = _test(table)
        curve, oracle = sparsification(t["uncertainty"], t["abs_error"])
        ax.plot(FRACTIONS, curve, label=name, linestyle="-" if name in PAPER_ESTIMATORS else ":")
    ax.plot(FRACTIONS, oracle, "k--", label="oracle")
    ax.set_xlabel("share of the most uncertain predictions removed")
    ax.set_ylabel("mean |error| left / mean |error|")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    _save(fig, path)


def plot_spearman_by_frame(by_frame: pd.DataFrame, path) -> None:
    """Within-frame Spearman of every estimator that ranks within a frame, against frames before the
    hit: where in the approach an uncertainty says something about a single hit's error."""
    fig, ax = plt.subplots(figsize=(6, 4))
    for name, g in by_frame.groupby("estimator", sort=False):
        if g["spearman"].notna().any():
            ax.plot(-g["frames_before_hit"], g["spearman"], marker=".",
                    linestyle="-" if name in PAPER_ESTIMATORS else ":", label=name)
    ax.axhline(0.0, color="k", linewidth=0.8)
    ax.set_xlabel("frames before the hit (100 Hz)")
    ax.set_ylabel("Spearman(uncertainty, |error|) within the frame")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    _save(fig, path)
