"""A run's results at a glance: the report tables turned into one Markdown table (reports/summary.md).

The README's results block is this file's content for a stated commit (docs/results/default_run.md,
checked by tests/test_readme.py), so every figure it quotes comes from a run's tables, never by hand.
"""

import numpy as np
import pandas as pd
from scipy.stats import bootstrap

from pingpong.curation.schemas import HIT_KEYS

TABLE1_FRAMES = (10, 1, 0)  # the paper's Table 1 (10 and 1 frames before the hit) and the hit itself
FRAME_LABELS = {10: "10 frames before the hit", 1: "1 frame before the hit", 0: "at the hit"}
PAPER_TABLE1_CM = {10: 26.27, 1: 16.65}  # the paper's Table 1, all regions
CONTROLLERS = {  # robot.csv's controllers, in the order of the paper's Tables 2-4 and then beyond them
    "servo": "visual servoing alone",
    "anticipatory": "basic anticipation",
    "uncertainty_aware": "uncertainty-aware (the paper's)",
    "confidence_scaled": "confidence-scaled (beyond the paper)",
    "confidence_scaled_oracle": "confidence-scaled on the oracle std (twin only)",
}


class SummaryError(ValueError):
    """A report table lacks what the summary reads; the message names the table and what is missing."""


def _require(table: pd.DataFrame, name: str, columns) -> None:
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise SummaryError(f"{name}: expected columns {missing}, found {list(table.columns)}")


def split_counts(predictions: pd.DataFrame) -> dict[str, int]:
    """Kept hits per split (train, calibration, test) from the final model's predictions."""
    _require(predictions, "predictions", [*HIT_KEYS, "model", "split"])
    final = predictions[predictions["model"] == "final"]
    return final.drop_duplicates(HIT_KEYS)["split"].value_counts().to_dict()


def _ratio(late, early, axis=-1):
    return np.median(late, axis=axis) / np.median(early, axis=axis)


def table1(predictions: pd.DataFrame, seed: int, n_resamples: int = 2000) -> pd.DataFrame:
    """Table 1 of the final model on the test hits: the median strike error (cm) at each of TABLE1_FRAMES
    and the ratio 1 frame / 10 frames, each with a 95 % percentile bootstrap interval over whole hits
    (paired: a hit keeps all its frames). Columns: quantity, value, low, high."""
    _require(predictions, "predictions", [*HIT_KEYS, "model", "split", "frames_before_hit", "abs_error"])
    test = predictions[(predictions["model"] == "final") & (predictions["split"] == "test")]
    errors = test.pivot_table(index=HIT_KEYS, columns="frames_before_hit", values="abs_error") * 100
    missing = [f for f in TABLE1_FRAMES if f not in errors.columns]
    if errors.empty or missing:
        raise SummaryError(f"predictions: the final model's test hits lack frames {missing or TABLE1_FRAMES}")
    rng = np.random.default_rng(seed)
    rows = []
    for frame in TABLE1_FRAMES:
        e = errors[frame].to_numpy()
        ci = _interval((e,), np.median, n_resamples, rng)
        rows.append((FRAME_LABELS[frame], np.median(e), *ci))
    late, early = errors[1].to_numpy(), errors[10].to_numpy()
    ci = _interval((late, early), _ratio, n_resamples, rng)
    rows.append(("1 frame / 10 frames", _ratio(late, early), *ci))
    return pd.DataFrame(rows, columns=["quantity", "value", "low", "high"])


def _interval(data, statistic, n_resamples, rng) -> tuple[float, float]:
    if len(data[0]) < 2:  # one hit has no spread to resample
        return np.nan, np.nan
    ci = bootstrap(data, statistic, paired=len(data) > 1, vectorized=True, n_resamples=n_resamples,
                   method="percentile", rng=rng).confidence_interval
    return float(ci.low), float(ci.high)


def checks_line(table: pd.DataFrame, name: str) -> str:
    """'n of m checks pass' of a twin accuracy table, naming each failing check with its value and bar."""
    _require(table, name, ["quantity", "value", "unit", "threshold", "must_be", "ok"])
    failed = table[~table["ok"].astype(bool)]
    line = f"{len(table) - len(failed)} of {len(table)} checks pass"
    if len(failed):
        bars = [f"{r.quantity} {r.value:.3g} {r.unit} ({r.must_be} {r.threshold:g} {r.unit})"
                for r in failed.itertuples()]
        line += "; failing: " + ", ".join(bars)
    return line


def robot_rows(robot: pd.DataFrame) -> list[tuple[str, str, str]]:
    """One row per controller over all test hits: hits of n, hit %, the gain over servoing with its 95 %
    interval; the paper's hits of its 223 where it has them."""
    _require(robot, "robot", ["controller", "region", "total", "hits", "hit_pct", "hits_minus_servo",
                              "diff_ci95_low", "diff_ci95_high", "paper_total", "paper_hits",
                              "paper_hit_pct"])
    rows = []
    for r in robot[robot["region"] == "all"].itertuples():
        ours = f"{r.hits} of {r.total} ({r.hit_pct:.1f} %)"
        if r.controller != "servo":
            ours += (f", {r.hits_minus_servo:+.0f} over servoing "
                     f"(95 % {r.diff_ci95_low:+.0f} to {r.diff_ci95_high:+.0f})")
        paper = "" if pd.isna(r.paper_hits) else (
            f"{r.paper_hits:.0f} of {r.paper_total:.0f} ({r.paper_hit_pct:.1f} %)")
        rows.append((f"robot: {CONTROLLERS.get(r.controller, r.controller)}", ours, paper))
    return rows


def uncertainty_line(verdict: pd.DataFrame) -> str:
    """The estimators that rank the twin's oracle std best (within frame, frames 1-20) with the 95 %
    interval, and how many meet every bar; without an oracle (a lab run) the best Spearman with the error."""
    _require(verdict, "uncertainty_verdict", ["estimator", "spearman_oracle_1_20", "oracle_low95",
                                              "oracle_high95", "spearman_error", "meets_all"])
    meets = int(verdict["meets_all"].astype(bool).sum())
    column = "spearman_oracle_1_20" if verdict["spearman_oracle_1_20"].notna().any() else "spearman_error"
    best = verdict[np.isclose(verdict[column], verdict[column].max())]
    what = "Spearman with the oracle std" if column == "spearman_oracle_1_20" else "Spearman with the error"
    line = f"best within-frame {what}: {verdict[column].max():.2f} ({', '.join(best['estimator'])})"
    if column == "spearman_oracle_1_20":
        first = best.iloc[0]
        line += f", 95 % {first.oracle_low95:.2f} to {first.oracle_high95:.2f}"
    return line + f"; {meets} of {len(verdict)} estimators meet every bar"


def summary_markdown(curation: pd.DataFrame, predictions: pd.DataFrame, strike_error: pd.DataFrame,
                     robot: pd.DataFrame, verdict: pd.DataFrame, commit: str, seed: int,
                     perception_accuracy: pd.DataFrame | None = None,
                     curation_accuracy: pd.DataFrame | None = None, n_resamples: int = 2000) -> str:
    """The results table of a run (Markdown), from its report tables; `commit` names the code that ran."""
    _require(curation, "curation", ["decision", "candidates"])
    _require(strike_error, "strike_error", ["model", "frames_before_hit", "all"])
    kept = int(curation.loc[curation["decision"] == "kept", "candidates"].sum())
    splits = split_counts(predictions)
    rows = [("hits kept", f"{kept} of {int(curation['candidates'].sum())} candidates ("
             + ", ".join(f"{splits.get(s, 0)} {s}" for s in ("train", "calibration", "test")) + ")", "")]
    for name, table in (("perception", perception_accuracy), ("curation", curation_accuracy)):
        if table is not None:
            rows.append((f"{name} against the twin's truth", checks_line(table, name), ""))
    t1 = table1(predictions, seed, n_resamples).set_index("quantity")
    for frame in TABLE1_FRAMES:
        r = t1.loc[FRAME_LABELS[frame]]
        paper = f"{PAPER_TABLE1_CM[frame]} cm" if frame in PAPER_TABLE1_CM else ""
        rows.append((f"Table 1: strike error {FRAME_LABELS[frame]}",
                     f"{r.value:.1f} cm (95 % {r.low:.1f} to {r.high:.1f})", paper))
    r = t1.loc["1 frame / 10 frames"]
    rows.append(("Table 1: 1 frame / 10 frames before", f"{r.value:.2f} (95 % {r.low:.2f} to {r.high:.2f})",
                 f"{PAPER_TABLE1_CM[1] / PAPER_TABLE1_CM[10]:.2f}"))
    baselines = strike_error[strike_error["frames_before_hit"] == 1].set_index("model")["all"]
    rows.append(("Table 1: 1 frame before, the ball alone / the training mean",
                 f"{baselines.get('ball_only', np.nan):.1f} / {baselines.get('mean', np.nan):.1f} cm", ""))
    rows += robot_rows(robot)
    rows.append(("uncertainty (uncertainty_verdict.md)", uncertainty_line(verdict), ""))
    lines = [f"Results of the run of commit {commit} (its `reports/tables/`; 95 % intervals: bootstrap over "
             "test hits).", "", "| | this run | the paper |", "|---|---|---|"]
    lines += [f"| {a} | {b} | {c} |" for a, b, c in rows]
    return "\n".join(lines) + "\n"
