"""The uncertainty report: every estimator's metrics on the test hits, and the paper's figures."""

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from pingpong.common.atomic import atomic_path  # noqa: E402
from pingpong.curation.schemas import HIT_KEYS  # noqa: E402
from pingpong.reports.uncertainty_oracle import as_uncertainty  # noqa: E402
from pingpong.uncertainty.metrics import (  # noqa: E402
    FRACTIONS,
    ause,
    coverage_by_width,
    ence,
    interval_metrics,
    sparsification,
    spearman,
    winkler_score,
    within_frames,
)
from pingpong.uncertainty.names import PAPER_ESTIMATORS  # noqa: E402
from pingpong.uncertainty.path_band import PathBand, path_band_table  # noqa: E402

SCATTER_ESTIMATORS = ("ensemble", "knn", "conformal", "cqr")  # the paper's three, and CQR beside them
LAST_FRAME = 0  # the paper's figure 3a-c: predictions made at t = 0, the hit frame


ORACLE = "oracle"  # the twin's strike oracle as a row: the ceiling no estimator fed the inputs can pass
ORACLE_FRAMES = range(1, 21)  # the bar: mean within-frame Spearman with the oracle std over these


def _test(table: pd.DataFrame) -> pd.DataFrame:
    return table[table["split"] == "test"]


def with_oracle(tables: dict[str, pd.DataFrame], oracle_rows: pd.DataFrame | None) -> dict[str, pd.DataFrame]:
    """Every estimator's test rows with the oracle std of their (hit, frame) (`oracle_std`, NaN unmatched),
    and the oracle itself as a table (uncertainty = std = its std, interval = its [q05, q95]).

    oracle_rows: uncertainty_oracle.join_test_hits (mirrored like the hits); None: no oracle (a lab run)."""
    keys = [*HIT_KEYS, "frames_before_hit"]
    out = {}
    for name, table in tables.items():
        test = _test(table).reset_index(drop=True)
        if oracle_rows is None:
            out[name] = test.assign(oracle_std=np.nan)
            continue
        std = oracle_rows[[*keys, "oracle_std_x"]].rename(columns={"oracle_std_x": "oracle_std"})
        out[name] = test.merge(std, on=keys, how="left", validate="one_to_one")
    if oracle_rows is not None and len(oracle_rows):
        base = out[next(iter(out))].drop(columns=["uncertainty", "lower", "upper", "std", "oracle_std"])
        rows = base.merge(oracle_rows[[*keys, "oracle_std_x", "oracle_q05_x", "oracle_q95_x"]], on=keys)
        out[ORACLE] = as_uncertainty(rows).assign(oracle_std=rows["oracle_std_x"])
    return out


def _centre(t: pd.DataFrame) -> np.ndarray:
    """The estimator's centre: its interval's midpoint, else the point prediction."""
    mid = (t["lower"] + t["upper"]).to_numpy(float) / 2
    return np.where(np.isfinite(mid), mid, t["strike_x_pred"].to_numpy(float))


def _ranking(t: pd.DataFrame) -> dict:
    u, e, f = (t[c].to_numpy(float) for c in ("uncertainty", "abs_error", "frames_before_hit"))
    o = t["oracle_std"].to_numpy(float)
    early = np.isin(f, ORACLE_FRAMES)
    has_oracle = np.isfinite(o)
    return {"spearman_pooled": spearman(u, e), "spearman_within_frame": within_frames(spearman, u, e, f),
            "spearman_oracle_within_frame": within_frames(spearman, u[has_oracle], o[has_oracle],
                                                          f[has_oracle]),
            "spearman_oracle_frames_1_20": within_frames(spearman, u[early & has_oracle],
                                                         o[early & has_oracle], f[early & has_oracle]),
            "ause_within_frame": within_frames(ause, u, e, f),
            "ause_oracle_within_frame": within_frames(ause, u[has_oracle], o[has_oracle], f[has_oracle])}


def _intervals(t: pd.DataFrame, alpha: float) -> dict:
    y, lower, upper = (t[c].to_numpy(float) for c in ("strike_x", "lower", "upper"))
    pooled = interval_metrics(y, lower, upper)
    if np.isnan(pooled["coverage"]):
        nan = float("nan")
        return {"coverage": nan, "coverage_min_frame": nan, "coverage_min_width_tercile": nan,
                "winkler_90_cm": nan, "mean_width_cm": nan, "width_sd_cm": nan}
    per_frame = [interval_metrics(g["strike_x"], g["lower"], g["upper"])["coverage"]
                 for _, g in t.groupby("frames_before_hit")]
    width = upper - lower
    return {"coverage": pooled["coverage"], "coverage_min_frame": float(np.min(per_frame)),
            "coverage_min_width_tercile": float(coverage_by_width(y, lower, upper).min()),
            "winkler_90_cm": 100 * winkler_score(y, lower, upper, alpha),
            "mean_width_cm": 100 * pooled["mean_width"],
            "width_sd_cm": 100 * float(np.std(width)) if np.isfinite(width).all() else float("nan")}


def summary_table(tables: dict[str, pd.DataFrame], coverage: float = 0.9) -> pd.DataFrame:
    """One row per estimator (and the oracle, when `with_oracle` gave one), on the test rows: ranking
    against the error and the oracle std (pooled, within frames), ENCE, the interval metrics (cm).
    tables: with_oracle's (or any test rows with an oracle_std column, NaN where none)."""
    rows = []
    for name, t in tables.items():
        t = _test(t) if "oracle_std" in t else _test(t).assign(oracle_std=np.nan)
        residual = t["strike_x"].to_numpy(float) - _centre(t)
        rows.append({"estimator": name, "paper": name in PAPER_ESTIMATORS, **_ranking(t),
                     "ence": ence(t["std"].to_numpy(float), residual), **_intervals(t, 1 - coverage),
                     "n_test_hits": t[HIT_KEYS].drop_duplicates().shape[0]})
    return pd.DataFrame(rows)


def by_frame_table(tables: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """Per estimator and frame before the hit: Spearman with the error and with the oracle std, AUSE,
    coverage, mean width and median error (cm)."""
    rows = []
    for name, table in tables.items():
        for frame, t in _test(table).groupby("frames_before_hit"):
            u, e = t["uncertainty"].to_numpy(), t["abs_error"].to_numpy()
            o = t["oracle_std"].to_numpy(float) if "oracle_std" in t else np.full(len(t), np.nan)
            interval = interval_metrics(t["strike_x"], t["lower"], t["upper"])
            rows.append({"estimator": name, "frames_before_hit": frame, "spearman": spearman(u, e),
                         "spearman_oracle": spearman(u[np.isfinite(o)], o[np.isfinite(o)]),
                         "ause": ause(u, e), "coverage": interval["coverage"],
                         "mean_width_cm": 100 * interval["mean_width"],
                         "median_error_cm": 100 * np.median(e)})
    return pd.DataFrame(rows)


def path_band_report(states: dict, dataset: pd.DataFrame, predictions: pd.DataFrame) -> pd.DataFrame:
    """The whole-path bands (estimators.json's path_band states) on the final model's test predictions:
    path_band.path_band_table, one row per band kind."""
    test = predictions[(predictions["model"] == "final") & (predictions["split"] == "test")]
    labels = dataset[[*HIT_KEYS, "a1", "a2", "b"]].rename(columns={c: f"{c}_true" for c in ("a1", "a2", "b")})
    rows = test.merge(labels, on=HIT_KEYS, validate="many_to_one")
    bands = [PathBand.from_state(state) for state in states.values()]
    table = path_band_table(bands, rows[["a1", "a2", "b"]].to_numpy(float),
                            rows[["a1_true", "a2_true", "b_true"]].to_numpy(float),
                            rows["frames_before_hit"].to_numpy())
    return table.reset_index().assign(n_test_hits=rows[HIT_KEYS].drop_duplicates().shape[0])


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


def plot_spearman_oracle_by_frame(by_frame: pd.DataFrame, path) -> None:
    """Per frame before the hit, each estimator's within-frame Spearman with the oracle std, and the
    oracle's own Spearman with the model's error (the most any uncertainty could rank the errors)."""
    fig, ax = plt.subplots(figsize=(7, 4.5))
    drawn = []  # an estimator that ranks like one drawn before it (a conformal scaling of it) is left out
    for name, g in by_frame.groupby("estimator", sort=False):
        rho = g["spearman_oracle"].to_numpy(float)
        if name == ORACLE:
            ax.plot(-g["frames_before_hit"], g["spearman"], "k-", lw=2, label="oracle std vs |error|")
        elif np.isfinite(rho).any() and not any(np.allclose(rho, d, equal_nan=True) for d in drawn):
            drawn.append(rho)
            ax.plot(-g["frames_before_hit"], rho, marker=".",
                    linestyle="-" if name in PAPER_ESTIMATORS else ":", label=name)
    if not by_frame["spearman_oracle"].notna().any():
        ax.text(0.5, 0.5, "no strike oracle (not a twin run)", transform=ax.transAxes, ha="center")
    ax.axhline(0.0, color="k", linewidth=0.8)
    ax.set_xlabel("frames before the hit (100 Hz)")
    ax.set_ylabel("Spearman with the oracle std, within the frame")
    ax.legend(fontsize=6, ncol=2)
    ax.grid(alpha=0.3)
    _save(fig, path)


def plot_coverage_by_width(tables: dict[str, pd.DataFrame], path, coverage: float = 0.9) -> None:
    """Coverage within each tercile of the interval width (narrowest first), one group per interval
    estimator, against the nominal coverage and the 85 % floor."""
    rows = {name: coverage_by_width(*(t[c].to_numpy(float) for c in ("strike_x", "lower", "upper")))
            for name, t in ((n, _test(t)) for n, t in tables.items()) if t["lower"].notna().any()}
    fig, ax = plt.subplots(figsize=(max(6, 0.6 * len(rows)), 4))
    x = np.arange(len(rows))
    for k, label in enumerate(("narrowest", "middle", "widest")):
        ax.bar(x + (k - 1) * 0.27, [v[k] for v in rows.values()], width=0.27, label=f"{label} third")
    ax.axhline(coverage, color="k", lw=1, label="nominal")
    ax.axhline(0.85, color="r", lw=1, ls="--", label="85 %")
    ax.set_xticks(x, list(rows), rotation=45, ha="right", fontsize=7)
    ax.set_ylim(0.5, 1.0)
    ax.set_ylabel("coverage within the width tercile")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3, axis="y")
    _save(fig, path)
