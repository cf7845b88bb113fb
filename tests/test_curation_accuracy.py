"""The curation accuracy report's matching on small synthetic tables (the real numbers: a twin run)."""

import numpy as np
import pandas as pd

from pingpong.frames import FRAME_NS
from pingpong.reports import curation_accuracy as acc

T0 = 1_767_225_600_000_000_000
MS = 1_000_000


def test_match_times_within_one_frame():
    found, real = acc.match_times(T0 + np.array([0, 500, 900]) * MS, T0 + np.array([3, 511, 700]) * MS)
    assert found.tolist() == [True, False, False]  # 11 ms is more than a frame
    assert real.tolist() == [True, False, False]
    found, real = acc.match_times([T0], [])
    assert found.tolist() == [False] and real.tolist() == []


def _truth():
    """A rally of a serve, an ok return, a net and an out ball that bounced once on the far half."""
    shots = pd.DataFrame({"rally": [0, 0, 1, 1, 1], "shot": [0, 1, 0, 1, 2],
                          "hitter": ["near", "far", "near", "far", "near"], "side": [1, -1, 1, -1, 1],
                          "t_hit_ns": T0 + np.array([0, 800, 3000, 3800, 4600]) * MS,
                          "outcome": ["ok", "net", "ok", "ok", "out"],
                          "strike_x": [0.1, np.nan, 0.2, -0.3, np.nan]})
    events = pd.DataFrame({
        "time_ns": T0 + np.array([0, 400, 800, 3000, 3400, 3800, 4200, 4600, 5000, 5600]) * MS,
        "kind": ["hit", "bounce", "hit", "hit", "bounce", "hit", "bounce", "hit", "bounce", "bounce"],
        "rally": [0, 0, 0, 1, 1, 1, 1, 1, 1, 1], "shot": [0, 0, 1, 0, 0, 1, 1, 2, 2, 2],
        "side": ["+y", "-y", "-y", "+y", "-y", "-y", "+y", "+y", "-y", "-y"]})
    return shots, events


def test_candidates_are_matched_to_the_nearest_true_shot_within_a_frame():
    shots, _ = _truth()
    shot_of = acc.nearest_shot(shots, T0 + np.array([806, 3795, 4200, 4600 + 10]) * MS)
    assert shot_of.tolist() == [1, 3, -1, 4]


def test_expected_decisions_follow_the_twins_outcome():
    shots, events = _truth()
    # without its last bounce shot 4 is 'out' having bounced once on the opponent's (-y) half, then
    # fallen beside the table: curation calls it no_strike_line
    expected = acc.expected_decisions(shots, events.drop(index=9), np.array([1, 3, 4, -1]))
    assert expected.tolist() == ["net", "kept", "no_strike_line", "not_a_hit"]
    assert acc.expected_decisions(shots, events, np.array([4])).tolist() == ["out"]  # two bounces there


def test_decision_rows_leave_data_quality_rejections_of_ok_returns_out():
    shots, events = _truth()
    segments = pd.DataFrame({"t_hit_ns": T0 + np.array([800, 3800, 4600, 4200]) * MS,
                             "decision": ["net", "pose_gaps", "kept", "kept"]})
    table = acc.decision_table([(segments, shots, events.drop(index=9))])
    assert table["data_quality"].tolist() == [False, True, False, False]
    rows = {r["quantity"]: r["value"] for r in acc.decision_rows(table)}
    assert rows["candidates that are true hits"] == 75.0
    assert np.isclose(rows["decisions agreeing with the twin's outcome"], 100 / 3)  # net agrees, 2 don't
    assert rows["kept candidates that are true ok returns"] == 0.0
    assert rows["true faults rejected as that fault"] == 100.0


def test_event_rows_skip_serves_and_unseen_bounces_but_count_detections_near_them_real():
    shots, events = _truth()
    ball = pd.DataFrame({"time_ns": T0 + np.arange(0, 6000) * MS, "vz": -3.0})
    ball.loc[ball["time_ns"] >= T0 + 5500 * MS, "vz"] = -0.5  # the last bounce is a dead ball's hop
    true = events[~events["time_ns"].isin(shots["t_hit_ns"][shots["shot"] == 0])]
    true = true[true["time_ns"] != T0 + 5600 * MS]
    detected = pd.DataFrame({"kind": [*true["kind"], "hit", "bounce", "bounce"],
                             "time_ns": [*(true["time_ns"] + 4 * MS), T0, T0 + 5600 * MS, T0 + 2000 * MS]})
    m = acc.event_matches(detected, events, shots, ball)
    assert m["hits_found"].all() and m["hits_real"].all() and m["bounces_found"].all()
    assert m["bounces_real"].tolist() == [True] * 5 + [False]  # one spurious bounce
    rows = {r["quantity"]: r for r in acc.event_rows([(detected, events, shots, ball)])}
    spurious = rows["spurious detected bounces"]
    assert np.isclose(spurious["value"], 100 / 6) and not spurious["ok"]
    assert rows["true hits found within a frame"]["ok"]


def test_filtering_and_label_rows():
    true = np.zeros((4, 3))
    ball3d = pd.DataFrame({"x": [0.002, 0.004, np.nan, 1.0], "y": 0.0, "z": 0.0})
    filtered = pd.DataFrame({"x": [0.001, 0.001, 0.0, np.nan], "y": 0.0, "z": 0.0})
    raw, low = acc.in_flight_errors(ball3d, filtered, true)
    assert np.allclose(raw, [0.002, 0.004]) and np.allclose(low, [0.001, 0.001])
    rows = acc.filtering_rows([(raw, low)])
    assert np.isclose(rows[1]["value"], 1.0) and rows[1]["threshold"] == rows[0]["value"] and rows[1]["ok"]
    shots, _ = _truth()
    segments = pd.DataFrame({"t_hit_ns": shots["t_hit_ns"].to_numpy()[[2, 3]] + FRAME_NS // 2,
                             "decision": ["kept", "kept"], "strike_x": [0.21, 0.30],
                             "strike_x_labels": [0.22, 0.33]})
    fit, measured = acc.label_rows([(segments, shots)])
    assert np.isclose(fit["value"], 2.0) and not fit["ok"]  # median of 1 and 3 cm: 2 cm is not below 2 cm
    assert np.isclose(measured["value"], 0.5)  # |0.21 - 0.2| and |0.30 - (-0.3 * -1)|
