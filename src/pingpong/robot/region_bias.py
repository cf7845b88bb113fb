"""The paper's left-region effect, measured: per region of the true strike point, the signed bias of the
predictions the anticipating robot moves on, and the end distance with and without anticipation.

The paper (Results, after Tables 2-4) reports that on left balls the basic anticipatory controller ends
farther from the ball than visual servoing (12.82 -> 13.63 cm), because the model, when unsure, predicts a
strike point of positive x in the centre region ("towards the center-right"), so the robot builds momentum
the wrong way. Here each part of that claim is a quantity with a bootstrap interval over the test hits:
  - strike bias: predicted minus true strike x at each prediction frame the controller uses
    (episode.anticipation_frames; t = -10 and t = 0 under the paper's timing);
  - wrong side: the share of hits whose prediction has x of the other sign than the truth (for left balls:
    x > 0, the paper's "positive x value");
  - end distance of servo and of basic anticipation (processed/sim/), and their paired difference.
"""

import numpy as np
import pandas as pd

from pingpong.curation.schemas import HIT_KEYS
from pingpong.robot.episode import EpisodeParams, anticipation_frames

REGIONS = ("left", "centre", "right", "all")
# The paper's Tables 2 and 3 (servo, basic anticipation): end distance mean, cm, per region
PAPER_END_DISTANCE_CM = {
    "servo": {"left": 12.82, "centre": 6.26, "right": 10.13, "all": 9.22},
    "anticipatory": {"left": 13.63, "centre": 5.9, "right": 8.33, "all": 8.42},
}
LEVEL = 0.95
EFFECT = "the paper's left-region effect (all three)"


def bootstrap_mean(values: np.ndarray, rng: np.random.Generator, n_boot: int) -> tuple[float, float, float]:
    """(mean, percentile 95 % interval) of the mean of `values` (one per hit) over resampled hits; NaNs
    dropped; NaN for no values."""
    values = np.asarray(values, float)
    values = values[np.isfinite(values)]
    if len(values) == 0:
        return np.nan, np.nan, np.nan
    means = values[rng.integers(0, len(values), size=(n_boot, len(values)))].mean(axis=1)
    tail = 100 * (1 - LEVEL) / 2
    low, high = np.percentile(means, [tail, 100 - tail])
    return float(values.mean()), float(low), float(high)


def used_predictions(predictions: pd.DataFrame, params: EpisodeParams) -> pd.DataFrame:
    """The rows of a PREDICTIONS table (one model's) at the frames whose goals the robot moves on, with the
    signed strike bias (m) and whether the prediction lies on the other side of x = 0 than the truth."""
    used = anticipation_frames(-predictions["frames_before_hit"].to_numpy(int), params)
    rows = predictions[used].copy()
    rows["bias_m"] = rows["strike_x_pred"] - rows["strike_x"]
    rows["wrong_side"] = (np.sign(rows["strike_x_pred"]) * np.sign(rows["strike_x"]) < 0).astype(float)
    return rows


def region_part(table: pd.DataFrame, region: str) -> pd.DataFrame:
    return table if region == "all" else table[table["region"] == region]


def bias_rows(predictions: pd.DataFrame, rng: np.random.Generator, n_boot: int) -> list[dict]:
    """Per region and used frame: mean signed bias (cm) and the wrong-side share (%), with intervals."""
    rows = []
    for frame, at_frame in reversed(list(predictions.groupby("frames_before_hit", sort=True))):
        for region in REGIONS:
            part = region_part(at_frame, region)
            for quantity, column, scale, unit in (("strike_bias", "bias_m", 100, "cm"),
                                                  ("wrong_side", "wrong_side", 100, "%")):
                mean, low, high = bootstrap_mean(scale * part[column].to_numpy(), rng, n_boot)
                rows.append({"region": region, "quantity": quantity, "frame": -int(frame),
                             "n_hits": len(part), "value": mean, "ci95_low": low, "ci95_high": high,
                             "unit": unit})
    return rows


def uncertainty_rows(predictions: pd.DataFrame, rng: np.random.Generator, n_boot: int) -> list[dict]:
    """Per used frame, the hits split at the median uncertainty of that frame: the mean predicted strike x
    (cm) of the unsure and the sure half over all regions (the paper: when unsure, the model predicts
    centre-right), and per region their signed bias. predictions: used_predictions rows with the
    configured estimator's 'uncertainty'."""
    rows = []
    for frame, at_frame in reversed(list(predictions.groupby("frames_before_hit", sort=True))):
        unsure = at_frame["uncertainty"] > at_frame["uncertainty"].median()
        for half, part in (("unsure", at_frame[unsure]), ("sure", at_frame[~unsure])):
            for region in REGIONS:
                in_region = region_part(part, region)
                quantities = [(f"strike_bias_{half}", in_region["bias_m"])]
                if region == "all":
                    quantities.append((f"predicted_x_{half}", in_region["strike_x_pred"]))
                for quantity, values in quantities:
                    mean, low, high = bootstrap_mean(100 * values.to_numpy(float), rng, n_boot)
                    rows.append({"region": region, "quantity": quantity, "frame": -int(frame),
                                 "n_hits": len(in_region), "value": mean, "ci95_low": low, "ci95_high": high,
                                 "unit": "cm"})
    return rows


def end_distance_rows(servo: pd.DataFrame, anticipatory: pd.DataFrame, rng: np.random.Generator,
                      n_boot: int) -> list[dict]:
    """Per region: end distance (cm) of servo and of basic anticipation, their paired difference, and the
    hits of each, on the same test hits (SIM tables)."""
    paired = servo.merge(anticipatory, on=[*HIT_KEYS, "region"], suffixes=("_servo", "_anticipatory"),
                         validate="one_to_one")
    if len(paired) != len(servo) or len(paired) != len(anticipatory):
        raise ValueError("servo and basic anticipation were not simulated on the same hits")
    rows = []
    for region in REGIONS:
        part = region_part(paired, region)
        servo_cm = 100 * part["end_distance_m_servo"].to_numpy(float)
        ant_cm = 100 * part["end_distance_m_anticipatory"].to_numpy(float)
        for quantity, values in (("end_distance_servo", servo_cm), ("end_distance_anticipatory", ant_cm),
                                 ("end_distance_change", ant_cm - servo_cm)):
            mean, low, high = bootstrap_mean(values, rng, n_boot)
            rows.append({"region": region, "quantity": quantity, "frame": np.nan, "n_hits": len(part),
                         "value": mean, "ci95_low": low, "ci95_high": high, "unit": "cm"})
        for quantity, hits in (("hits_servo", part["hit_ball_servo"]),
                               ("hits_anticipatory", part["hit_ball_anticipatory"])):
            rows.append({"region": region, "quantity": quantity, "frame": np.nan, "n_hits": len(part),
                         "value": float(hits.sum()), "ci95_low": np.nan, "ci95_high": np.nan,
                         "unit": "balls"})
    return rows


def paper_values(table: pd.DataFrame) -> pd.Series:
    """The paper's end distances beside ours (NaN where it gives none)."""
    servo, ant = PAPER_END_DISTANCE_CM["servo"], PAPER_END_DISTANCE_CM["anticipatory"]
    lookup = {"end_distance_servo": servo, "end_distance_anticipatory": ant,
              "end_distance_change": {r: round(ant[r] - servo[r], 2) for r in servo}}
    return pd.Series([lookup.get(q, {}).get(r, np.nan) for q, r in zip(table["quantity"], table["region"],
                                                                         strict=True)], index=table.index)


def effect_verdict(table: pd.DataFrame) -> pd.DataFrame:
    """The three parts of the paper's claim on left balls, each 'shows' when its 95 % interval excludes
    no effect: the predictions lean right (bias > 0, at every used frame), some go to the wrong side
    (share > 0, at the last used frame, the one the robot moves on when the ball is hit), the end distance
    grows with anticipation (change > 0). The last row: all three."""
    left = table[table["region"] == "left"]
    bias = left[left["quantity"] == "strike_bias"]
    first = left["frame"].min()  # the robot's first move, where momentum the wrong way starts
    wrong = left[(left["quantity"] == "wrong_side") & (left["frame"] == first)]
    change = left[left["quantity"] == "end_distance_change"]
    shows = lambda rows: bool(len(rows)) and bool((rows["ci95_low"] > 0).all())  # noqa: E731
    parts = {
        "left balls predicted towards the right (strike bias > 0 at every used frame)": shows(bias),
        "left balls predicted on the wrong side (x > 0) at the first used frame": shows(wrong),
        "left end distance grows with anticipation (change > 0)": shows(change),
    }
    parts[EFFECT] = all(parts.values())
    # beside it, not part of it: a lean to the right over all balls (the paper's explanation, a right
    # skew), rather than a pull towards the middle (which leans left balls right and right balls left)
    overall = table[(table["region"] == "all") & (table["quantity"] == "strike_bias")]
    parts["all balls predicted towards the right (strike bias > 0 at every used frame)"] = shows(overall)
    unsure = table[table["quantity"] == "predicted_x_unsure"]
    if len(unsure):
        parts["unsure predictions lie right of the middle (mean predicted x of the more uncertain half > 0 "
              "at every used frame)"] = shows(unsure)
    n_left = int(change["n_hits"].iloc[0]) if len(change) else 0
    return pd.DataFrame({"region": "left", "quantity": "paper_effect", "frame": np.nan, "n_hits": n_left,
                         "value": [float(v) for v in parts.values()], "ci95_low": np.nan, "ci95_high": np.nan,
                         "unit": "shows (1) / not (0)", "claim": list(parts)})


def region_bias_table(predictions: pd.DataFrame, servo: pd.DataFrame, anticipatory: pd.DataFrame,
                      params: EpisodeParams, rng: np.random.Generator, n_boot: int,
                      uncertainty: pd.DataFrame | None = None) -> pd.DataFrame:
    """The region-bias table: predictions (PREDICTIONS rows of the final model on the test hits), servo and
    anticipatory (their SIM tables), params: the timing whose anticipation frames the robot uses;
    uncertainty: the configured estimator's table (None: no rows by uncertainty)."""
    used = used_predictions(predictions, params)
    rows = bias_rows(used, rng, n_boot)
    if uncertainty is not None:
        keys = [*HIT_KEYS, "frames_before_hit"]
        used = used.merge(uncertainty[[*keys, "uncertainty"]], on=keys, how="left", validate="one_to_one")
        rows += uncertainty_rows(used, rng, n_boot)
    rows += end_distance_rows(servo, anticipatory, rng, n_boot)
    table = pd.DataFrame(rows)
    table["paper_value"] = paper_values(table)
    table["claim"] = ""
    return pd.concat([table, effect_verdict(table)], ignore_index=True)


def effect_shows(table: pd.DataFrame) -> bool:
    """Whether the region-bias table finds the paper's left-region effect (all three parts)."""
    return bool(table.loc[table["claim"] == EFFECT, "value"].iloc[0])
