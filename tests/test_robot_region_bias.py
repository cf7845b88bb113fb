"""The paper's left-region effect (pingpong.robot.region_bias) on synthetic predictions and episodes of
known bias and end distance; and the tiny run's tables."""

import numpy as np
import pandas as pd
import pytest

from pingpong.frames import region_of
from pingpong.robot.episode import EpisodeParams
from pingpong.robot.region_bias import EFFECT, effect_shows, region_bias_table

BIAS = {"left": 0.35, "centre": 0.05, "right": -0.1}  # m, predicted minus true


def synthetic(n: int = 120, left_change_m: float = 0.03, seed: int = 0):
    """PREDICTIONS rows (frames 0..30 before the hit) with a constant bias per region, and servo and
    anticipatory SIM rows whose left end distance grows by left_change_m with anticipation."""
    rng = np.random.default_rng(seed)
    strike_x = rng.uniform(-0.7, 0.7, n)
    region = region_of(strike_x)
    hits = pd.DataFrame({"session": "s00", "rally": np.arange(n) // 5, "hit": np.arange(n) % 5,
                         "region": region, "strike_x": strike_x})
    frames = np.arange(31)
    predictions = hits.loc[hits.index.repeat(len(frames))].reset_index(drop=True)
    predictions["frames_before_hit"] = np.tile(frames, n)
    predictions["strike_x_pred"] = predictions["strike_x"] + predictions["region"].map(BIAS)
    servo_m = rng.uniform(0.02, 0.1, n)
    change = np.where(region == "left", left_change_m, -0.01)
    servo = hits.assign(end_distance_m=servo_m, hit_ball=servo_m < 0.08)
    anticipatory = hits.assign(end_distance_m=servo_m + change, hit_ball=servo_m + change < 0.08)
    return predictions, servo, anticipatory


def rng():
    return np.random.default_rng(0)


def value(table, region, quantity, frame=None):
    rows = table[(table["region"] == region) & (table["quantity"] == quantity)]
    if frame is not None:
        rows = rows[rows["frame"] == frame]
    assert len(rows) == 1
    return rows.iloc[0]


def test_bias_per_region_at_the_used_frames():
    """The signed bias of each region, at exactly the frames the paper's timing moves on (t = -10, 0)."""
    predictions, servo, anticipatory = synthetic()
    table = region_bias_table(predictions, servo, anticipatory, EpisodeParams(), rng(), 500)
    assert sorted(table.loc[table["quantity"] == "strike_bias", "frame"].unique()) == [-10, 0]
    for region, bias in BIAS.items():
        row = value(table, region, "strike_bias", frame=-10)
        assert row["value"] == pytest.approx(100 * bias)
        assert row["ci95_low"] <= 100 * bias <= row["ci95_high"]
    # a prediction on the other side of x = 0 than the truth: left balls within 0.35 m of it
    left = predictions[(predictions["region"] == "left") & (predictions["frames_before_hit"] == 0)]
    expected = 100 * np.mean(left["strike_x"] > -0.35)
    assert 0 < expected < 100
    assert value(table, "left", "wrong_side", frame=0)["value"] == pytest.approx(expected)


def test_end_distance_paired_change():
    predictions, servo, anticipatory = synthetic(left_change_m=0.03)
    table = region_bias_table(predictions, servo, anticipatory, EpisodeParams(), rng(), 500)
    change = value(table, "left", "end_distance_change")
    assert change["value"] == pytest.approx(3.0)
    assert value(table, "centre", "end_distance_change")["value"] == pytest.approx(-1.0)
    assert value(table, "all", "hits_servo")["value"] == servo["hit_ball"].sum()
    assert value(table, "left", "end_distance_servo")["paper_value"] == 12.82


def test_effect_verdict():
    """The effect shows when left balls lean right with some on the wrong side and their end distance
    grows with anticipation; not when it shrinks."""
    shows = region_bias_table(*synthetic(left_change_m=0.03), EpisodeParams(), rng(), 500)
    assert effect_shows(shows)
    claims = shows.loc[shows["quantity"] == "paper_effect", "claim"].tolist()
    assert EFFECT in claims and len(claims) == 5
    shrinks = region_bias_table(*synthetic(left_change_m=-0.02), EpisodeParams(), rng(), 500)
    assert not effect_shows(shrinks)


def test_mismatched_hits_refused():
    predictions, servo, anticipatory = synthetic()
    with pytest.raises(ValueError, match="same hits"):
        region_bias_table(predictions, servo, anticipatory.iloc[1:], EpisodeParams(), rng(), 100)


@pytest.mark.slow
def test_tiny_run_tables(tiny_run):
    """The tiny run writes both tables, with their rows."""
    bias = pd.read_csv(tiny_run / "reports/tables/robot_region_bias.csv")
    assert {"strike_bias", "end_distance_change", "paper_effect"} <= set(bias["quantity"])
    risk = pd.read_csv(tiny_run / "reports/tables/robot_risk_control.csv")
    assert (risk["kind"] == "summary").sum() == risk["predictions"].nunique()
    assert set(risk["predictions"]) == {"model", "mirrored"}
    assert (tiny_run / "reports/pages/robot/robot_risk_control.html").exists()


def test_rows_by_uncertainty():
    """With an uncertainty table: each used frame's hits split at the median uncertainty; the unsure half's
    mean predicted x and per-region bias, and the claim that unsure predictions lie right of the middle."""
    predictions, servo, anticipatory = synthetic()
    unsure = predictions["rally"] % 2 == 0  # half the hits (whole rallies) unsure at every frame
    predictions.loc[unsure, "strike_x_pred"] = 0.15  # when unsure: centre-right
    uncertainty = predictions[["session", "rally", "hit", "frames_before_hit"]].assign(
        uncertainty=np.where(unsure, 0.5, 0.1))
    table = region_bias_table(predictions, servo, anticipatory, EpisodeParams(), rng(), 500, uncertainty)
    for frame in (-10, 0):
        assert value(table, "all", "predicted_x_unsure", frame)["value"] == pytest.approx(15.0)
        sure = predictions[~unsure & (predictions["frames_before_hit"] == -frame)]
        assert value(table, "all", "predicted_x_sure", frame)["value"] == pytest.approx(
            100 * sure["strike_x_pred"].mean())
    claim = table[table["claim"].str.startswith("unsure predictions", na=False)]
    assert claim["value"].tolist() == [1.0]
    plain = region_bias_table(predictions, servo, anticipatory, EpisodeParams(), rng(), 100)
    assert "predicted_x_unsure" not in set(plain["quantity"])
