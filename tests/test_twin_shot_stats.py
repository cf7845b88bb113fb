"""Shot statistics of the twin beside published figures (pingpong.reports.twin_shots, published_shots)."""

import numpy as np
import pandas as pd
import pytest

from pingpong.reports.published_shots import NOT_FOUND, PUBLISHED, published_for
from pingpong.reports.twin_shots import (
    STATISTICS,
    first_bounce_depths,
    good_shot_table,
    percentiles,
    shot_stats_table,
    spin_types,
    write_sections,
)

TOWARDS_FAR = np.array([0.0, -10.0, 1.0])  # the near player's (+y) shot, slightly upwards


def test_spin_types_of_hand_made_vectors():
    w = np.array([
        [150.0, 0.0, 0.0],  # about +x for a ball going -y: the top moves forward, F = w x v points down
        [-150.0, 0.0, 0.0],  # the reverse: F points up
        [0.0, 0.0, 150.0],  # about the vertical: F horizontal, across the flight
        [0.0, 0.0, -150.0],
        [0.0, -150.0, 15.0],  # about the flight direction (gyro spin): no Magnus force
        [0.0, 0.0, 0.0],
    ])
    v = np.tile(TOWARDS_FAR, (len(w), 1))
    v[4] = [0.0, -10.0, 1.0]
    assert list(spin_types(w, v)) == ["topspin", "backspin", "sidespin", "sidespin", "none", "none"]
    # the far player's shot (going +y) with topspin spins about -x
    assert list(spin_types([[-150.0, 0.0, 0.0]], [[0.0, 10.0, 0.0]])) == ["topspin"]


def test_sidespin_dominance_threshold_at_half_of_the_force():
    v = np.array([[0.0, -10.0, 0.0]])
    # F = w x v for w = (a, 0, c): (10 c, 0, -10 a); its across-flight part is |10 c|, F_z = -10 a
    tilted = lambda deg: [[-np.cos(np.radians(deg)), 0.0, np.sin(np.radians(deg))]]  # noqa: E731
    assert spin_types(tilted(25), v)[0] == "backspin"  # F 25 deg off the vertical: across share 0.42
    assert spin_types(tilted(35), v)[0] == "sidespin"  # 35 deg: 0.57 > 1/2
    assert spin_types([[np.cos(np.radians(25)), 0.0, np.sin(np.radians(25))]], v)[0] == "topspin"
    # a vertical flight: all of F is horizontal and across it
    assert spin_types([[100.0, 0.0, 0.0]], [[0.0, 0.0, 5.0]])[0] == "sidespin"


def test_percentiles_of_a_synthetic_table():
    table = pd.DataFrame({"speed": np.arange(101.0)})
    assert percentiles(table["speed"]) == pytest.approx((10.0, 50.0, 90.0))
    assert percentiles([1.0, np.nan, 3.0]) == pytest.approx((1.2, 2.0, 2.8))
    assert all(np.isnan(percentiles([])))


def test_first_bounce_depth_is_the_earliest_bounce_of_the_rally_and_shot():
    columns = ["time_ns", "kind", "rally", "shot", "side", "x", "y", "z"]
    events = pd.DataFrame([  # deliberately out of time order
        (3_000, "bounce", 0, 0, "-y", 0.1, -1.20, 0.0),
        (1_000, "hit", 0, 0, "+y", 0.0, 1.60, 0.2),
        (2_000, "bounce", 0, 0, "-y", 0.1, -0.45, 0.0),
        (4_500, "net", 0, 1, "+y", 0.0, 0.00, 0.1),
        (4_000, "bounce", 0, 1, "+y", 0.0, 0.30, 0.0),
        (9_000, "bounce", 1, 0, "-y", 0.0, -0.90, 0.0),
    ], columns=columns)
    shots = pd.DataFrame({"rally": [0, 0, 1, 2], "shot": [1, 0, 0, 0]})
    np.testing.assert_allclose(first_bounce_depths(shots, events), [0.30, 0.45, 0.90, np.nan])


def _shots(n_per_stroke=4, strokes=("drive", "push")):
    rows = []
    for k, stroke in enumerate(np.repeat(strokes, n_per_stroke)):
        spin = [150.0, 0.0, 0.0] if stroke != "push" else [-60.0, 0.0, 0.0]
        rows.append({"rally": k, "shot": 0, "hitter": "near", "side": 1, "outcome": "ok", "stroke": stroke,
                     "v_out_x": 0.0, "v_out_y": -(8.0 + k), "v_out_z": 1.0, "w_out_x": spin[0],
                     "w_out_y": spin[1], "w_out_z": spin[2]})
    rows.append({**rows[0], "rally": 99, "outcome": "net"})  # not a good shot
    events = pd.DataFrame([{"time_ns": k, "kind": "bounce", "rally": k, "shot": 0, "side": "-y", "x": 0.0,
                            "y": -0.15 - 0.1 * k, "z": 0.0} for k in range(len(rows) - 1)])
    return pd.DataFrame(rows), events


def test_good_shot_table_and_per_stroke_rows():
    shots, events = _shots()
    good = good_shot_table(shots, events)
    assert len(good) == 8 and list(good["stroke"]) == ["drive"] * 4 + ["push"] * 4
    np.testing.assert_allclose(good["spin"].iloc[0], 150.0 / (2 * np.pi))
    table = shot_stats_table(good).set_index(["statistic", "stroke"])
    assert table.loc[(STATISTICS["speed"][0], "all"), "n"] == 8
    assert table.loc[(STATISTICS["backspin_share"][0], "all"), "twin"] == pytest.approx(0.5)
    assert table.loc[(STATISTICS["backspin_share"][0], "push"), "twin"] == pytest.approx(1.0)
    assert table.loc[(STATISTICS["backspin_share"][0], "drive"), "twin"] == pytest.approx(0.0)
    push_speeds = [np.hypot(8.0 + k, 1.0) for k in range(4, 8)]
    assert table.loc[(STATISTICS["speed"][0], "push"), "twin"] == pytest.approx(np.median(push_speeds))
    # bounces 0.15 ... 0.85 m from the net: 0.15-0.65 are in the 0.10-0.70 m band (6 of 8)
    assert table.loc[(STATISTICS["bounce_in_band"][0], "all"), "twin"] == pytest.approx(6 / 8)
    assert table.loc[(STATISTICS["spin"][0], "push"), "published (human play)"] == NOT_FOUND


def test_missing_stroke_column_gives_the_overall_rows_only():
    shots, events = _shots()
    good = good_shot_table(shots.drop(columns="stroke"), events)
    assert good["stroke"].isna().all()
    table = shot_stats_table(good)
    assert set(table["stroke"]) == {"all"} and len(table) == 8
    with pytest.raises(ValueError, match="v_out_x"):
        good_shot_table(shots.drop(columns="v_out_x"), events)


def test_published_records_are_complete_and_looked_up():
    for record in PUBLISHED:
        assert record.statistic in STATISTICS and record.figure and record.source and record.url
    figure, source = published_for("spin", "all")
    assert " / " in figure and "hal-04557947" in source
    assert published_for("sidespin_share", "all") == (NOT_FOUND, "")


def test_write_sections_stacks_the_tables(tmp_path):
    a, b = pd.DataFrame({"quantity": ["q"], "x": [1.0]}), pd.DataFrame({"statistic": ["s"], "y": [2.0]})
    write_sections(tmp_path / "t.md", tmp_path / "t.csv", "Title", [("one", "One", "First.", a),
                                                                     ("two", "Two", "Second.", b)])
    text = (tmp_path / "t.md").read_text()
    assert text.startswith("# Title\n\nFirst.\n\n|") and "## Two\n\nSecond." in text
    assert "## One" not in text
    stacked = pd.read_csv(tmp_path / "t.csv")
    assert list(stacked["section"]) == ["one", "two"] and list(stacked.columns[:1]) == ["section"]
