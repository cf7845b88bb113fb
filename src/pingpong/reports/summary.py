"""A run's results at a glance: the report tables turned into one Markdown table (reports/summary.md).

The README's results block is this file's content for a stated commit (docs/results/default_run.md,
checked by tests/test_readme.py), so every figure it quotes comes from a run's tables, never by hand.
"""

from pathlib import Path

import numpy as np
import pandas as pd
from scipy.stats import bootstrap

from pingpong.common.artifacts import read_table
from pingpong.curation.schemas import HIT_KEYS
from pingpong.learning.schemas import PREDICTIONS

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


# tables a run may lack: the twin's (a lab run has none), risk control's (no estimator configured)
EXTRA_TABLES = ("twin_vs_real", "twin_keypoints", "robot_regimes", "robot_regime_calibration",
                "robot_risk_control", "uncertainty_learnability")


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
        ci = bootstrap_interval((e,), np.median, n_resamples, rng)
        rows.append((FRAME_LABELS[frame], np.median(e), *ci))
    late, early = errors[1].to_numpy(), errors[10].to_numpy()
    ci = bootstrap_interval((late, early), _ratio, n_resamples, rng)
    rows.append(("1 frame / 10 frames", _ratio(late, early), *ci))
    return pd.DataFrame(rows, columns=["quantity", "value", "low", "high"])


def bootstrap_interval(data, statistic, n_resamples, rng) -> tuple[float, float]:
    """The 95 % percentile bootstrap interval of statistic over data (arrays resampled together, paired,
    when more than one); NaN where there is one value or none."""
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


def learnability_line(table: pd.DataFrame) -> str:
    """The learnability ceiling (a net trained on the oracle std itself), the same net trained on the model's
    errors, and the best estimator's share of the ceiling (uncertainty_learnability.md)."""
    _require(table, "uncertainty_learnability", ["kind", "spearman_oracle_1_20", "low95", "high95",
                                                 "share_of_ceiling", "name"])
    rows = table.set_index("kind")
    best = table[table["kind"] == "estimator"].sort_values("spearman_oracle_1_20").iloc[-1]
    labels = (("a net trained on the oracle std itself", "ceiling"),
              ("on the model's errors", "single draws"))
    text = [f"{label} {rows.loc[kind, 'spearman_oracle_1_20']:.2f} (95 % {rows.loc[kind, 'low95']:.2f} to "
            f"{rows.loc[kind, 'high95']:.2f})" for label, kind in labels]
    return "; ".join(text) + f"; the best estimator ({best['name']}) at {best.share_of_ceiling:.2f} of it"


def rejections(curation: pd.DataFrame) -> str:
    """The candidates each curation rule rejected, in the rules' order, those with any."""
    rejected = curation[(curation["decision"] != "kept") & (curation["candidates"] > 0)]
    return ", ".join(f"{r.decision} {r.candidates}" for r in rejected.itertuples())


def joints_line(perception_accuracy: pd.DataFrame) -> str:
    """The 8 model joints' median 3D error against the twin's truth, over the sessions."""
    errors = perception_accuracy.loc[perception_accuracy["quantity"] == "8-joint 3D error (median)", "value"]
    return f"median {errors.median():.1f} cm (sessions {errors.min():.1f} to {errors.max():.1f})"


def twin_rows(twin_vs_real: pd.DataFrame | None, keypoints: pd.DataFrame | None) -> list[tuple]:
    """What the twin's play and its keypoint detector look like: net-crossing heights and speeds of the
    good shots (twin_vs_real's net section), the 2D keypoint errors and false people (twin_keypoints)."""
    rows = []
    if twin_vs_real is not None and (twin_vs_real["section"] == "net").any():
        net = twin_vs_real[(twin_vs_real["section"] == "net") & (twin_vs_real["stroke"] == "all")]
        height = net[net["statistic"].str.startswith("net-crossing height")].iloc[0]
        high = net[net["statistic"].str.startswith("share crossing")].iloc[0]
        speed = net[net["statistic"].str.startswith("speed at the net")].iloc[0]
        rows.append(("twin: the good shots' height over the net",
                     f"p10 / median / p90 {100 * height.twin_p10:.1f} / {100 * height.twin:.1f} / "
                     f"{100 * height.twin_p90:.1f} cm, {100 * high.twin:.1f} % above 25 cm; speed at the net "
                     f"{speed.twin:.1f} m/s (median) ({height.n:.0f} shots)", ""))
    if keypoints is not None:
        joints = keypoints[keypoints["table"] == "joints"]
        px, share = joints["median_px"], joints["median_per_height_pct"]
        false_people = keypoints.loc[keypoints["table"] == "cameras", "false_people_frames_pct"].max()
        rows.append(("twin: 2D keypoint errors (twin_keypoints.md)",
                     f"median {px.min():.1f} to {px.max():.1f} px by joint ({share.min():.1f} to "
                     f"{share.max():.1f} % of the person's height); false people in up to "
                     f"{false_people:.0f} % of a camera's frames", ""))
    return rows


def _interval_text(value, low, high) -> str:
    return f"{value:+.0f} (95 % {low:+.0f} to {high:+.0f})"


def regime_rows(regimes: pd.DataFrame) -> list[tuple[str, str, str]]:
    """Per named regime the balls anticipation wins over servoing and uncertainty over anticipation, with
    their paired intervals; the grid's cells summed up as where each pays (interval above zero)."""
    rows = []
    grid = regimes["cell"].str.contains("__")
    for r in regimes[~grid].itertuples():
        anticipation = _interval_text(r.anticipation_value, r.anticipation_ci95_low, r.anticipation_ci95_high)
        uncertainty = _interval_text(r.uncertainty_value, r.uncertainty_ci95_low, r.uncertainty_ci95_high)
        rows.append((f"robot regime {r.cell}: servoing / anticipation / perfect predictions",
                     f"{r.hits_servo} / {r.hits_anticipatory} / {r.hits_perfect} of {r.n_test}; anticipation "
                     f"{anticipation}, uncertainty ({r.uncertainty_controller}) {uncertainty}", ""))
    cells = regimes[grid]
    if len(cells):
        pays = int((cells["anticipation_ci95_low"] > 0).sum())
        unc = int((cells["uncertainty_ci95_low"] > 0).sum())
        costs = int((cells["uncertainty_ci95_high"] < 0).sum())
        monotone = int((~cells["alpha_monotone"].astype(bool)).sum())
        rows.append(("robot regime map (robot_regimes.md)",
                     f"over {len(cells)} cells: anticipation pays in {pays}, uncertainty pays in {unc} and "
                     f"costs balls in {costs}; the alpha sweep has an interior optimum in {monotone}", ""))
    return rows


def calibrated_regime_rows(calibration: pd.DataFrame) -> list[tuple[str, str, str]]:
    """Servoing alone in each regime calibrated to the paper's Table 2, by region (hit rate with its 95 %
    Clopper-Pearson interval), beside the paper's."""
    rows = []
    for regime, table in calibration.groupby("regime", sort=False):
        parts = [f"{r.region} {r.hit_pct:.0f} % (95 % {r.hit_pct_ci95_low:.0f} to {r.hit_pct_ci95_high:.0f}; "
                 f"paper {r.paper_hit_pct:.0f} %), {r.end_distance_mean_cm:.1f} cm (paper "
                 f"{r.paper_end_distance_cm:.1f})" for r in table.itertuples()]
        rows.append((f"robot regime {regime}: servoing by region on the test hits", "; ".join(parts), ""))
    return rows


def risk_control_line(risk: pd.DataFrame) -> str:
    """How often the risk-controlled anticipation's test miss rate exceeded servoing's plus epsilon over the
    re-splits, beside how often delta allows, with the mean chosen lambda and miss rates."""
    model = risk[risk["predictions"] == "model"]
    summary = model[model["kind"] == "summary"].iloc[0]
    resplits = model[model["kind"] == "re-split"]
    miss = resplits[["risk_controlled_miss_pct", "servo_miss_pct", "anticipatory_miss_pct"]].mean()
    return (f"test miss rate over servoing's + {summary.epsilon_pct:.0f} points in {summary.exceeds:.0f} of "
            f"{summary.n_resplits:.0f} re-splits (at most {summary.allowed_exceedances:.0f} allowed); mean "
            f"lambda {resplits['lambda'].mean():.2f}, misses {miss.iloc[0]:.1f} % against servoing's "
            f"{miss.iloc[1]:.1f} % and basic anticipation's {miss.iloc[2]:.1f} %")


def run_tables(root) -> dict:
    """summary_markdown's tables (but commit and seed) as a finished run in folder `root` wrote them: the
    generator of docs/results/ and the tests read a run this way; the rule reads its inputs."""
    tables = Path(root) / "reports/tables"
    out = {name: pd.read_csv(tables / f"{table}.csv") for name, table in (
        ("curation", "curation"), ("strike_error", "strike_error"), ("robot", "robot"),
        ("verdict", "uncertainty_verdict"))}
    out["predictions"] = read_table(Path(root) / "processed/predictions.parquet", PREDICTIONS)
    for name in ("perception_accuracy", "curation_accuracy"):
        if (tables / f"{name}.csv").is_file():
            out[name] = pd.read_csv(tables / f"{name}.csv")
    out["extra"] = {name: pd.read_csv(tables / f"{name}.csv") for name in EXTRA_TABLES
                    if (tables / f"{name}.csv").is_file()}
    return out


def summary_markdown(curation: pd.DataFrame, predictions: pd.DataFrame, strike_error: pd.DataFrame,
                     robot: pd.DataFrame, verdict: pd.DataFrame, commit: str, seed: int,
                     perception_accuracy: pd.DataFrame | None = None,
                     curation_accuracy: pd.DataFrame | None = None, n_resamples: int = 2000,
                     extra: dict[str, pd.DataFrame] | None = None) -> str:
    """The results table of a run (Markdown), from its report tables; `commit` names the code that ran.
    `extra`: the tables a run may lack (EXTRA_TABLES), by name."""
    extra = extra or {}
    _require(curation, "curation", ["decision", "candidates"])
    _require(strike_error, "strike_error", ["model", "frames_before_hit", "all"])
    kept = int(curation.loc[curation["decision"] == "kept", "candidates"].sum())
    splits = split_counts(predictions)
    rows = [("hits kept", f"{kept} of {int(curation['candidates'].sum())} candidates ("
             + ", ".join(f"{splits.get(s, 0)} {s}" for s in ("train", "calibration", "test"))
             + f"); rejected: {rejections(curation) or 'none'}", "")]
    rows += twin_rows(extra.get("twin_vs_real"), extra.get("twin_keypoints"))
    for name, table in (("perception", perception_accuracy), ("curation", curation_accuracy)):
        if table is not None:
            rows.append((f"{name} against the twin's truth", checks_line(table, name), ""))
    if perception_accuracy is not None:
        rows.append(("3D joints against the twin's truth", joints_line(perception_accuracy), ""))
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
    if "uncertainty_learnability" in extra:
        rows.append(("uncertainty: what the inputs allow (uncertainty_learnability.md)",
                     learnability_line(extra["uncertainty_learnability"]), ""))
    if "robot_regimes" in extra:
        rows += regime_rows(extra["robot_regimes"])
    if "robot_regime_calibration" in extra:
        rows += calibrated_regime_rows(extra["robot_regime_calibration"])
    if "robot_risk_control" in extra:
        rows.append(("robot: risk-controlled anticipation (robot_risk_control.md)",
                     risk_control_line(extra["robot_risk_control"]), ""))
    lines = [f"Results of the run of commit {commit} (its `reports/tables/`; 95 % intervals: bootstrap over "
             "test hits).", "", "| | this run | the paper |", "|---|---|---|"]
    lines += [f"| {a} | {b} | {c} |" for a, b, c in rows]
    return "\n".join(lines) + "\n"
