"""Perception stages against the twin's truth on the shared tiny run (thresholds of the perception issue)."""

import json

import numpy as np
import pandas as pd
from workflow_util import ROOT

from pingpong.common.artifacts import read_table
from pingpong.common.camera import Camera
from pingpong.common.config import schema_defaults
from pingpong.perception.calibration import load_cameras
from pingpong.perception.schemas import BALL3D, DETECTIONS
from pingpong.perception.triangulation import reprojection_gate_px, triangulate_robust
from pingpong.reports.perception_accuracy import calibration_rows, detection_rows, paddle_rows
from pingpong.twin import truth


def _failed(rows):
    return [r for r in rows if not r["ok"]]


def test_calibration_reprojection_under_half_a_pixel_and_centres_within_1_cm(tiny_run):
    calibrated = json.loads((tiny_run / "interim/calibration/cameras.json").read_text())
    truth = json.loads((tiny_run / "raw/twin_truth/rig.json").read_text())
    rows = calibration_rows([Camera.from_dict(c) for c in calibrated["cameras"]], calibrated["reports"],
                            [Camera.from_dict(c) for c in truth["cameras"]])
    assert len(rows) == 6 and not _failed(rows), rows
    assert calibrated["optitrack_fit_rms_m"] < 0.001


def test_paddles_within_2_mm_and_1_degree_with_gaps_marked(tiny_run):
    measured = pd.read_parquet(tiny_run / "interim/paddle/s00.parquet")
    truth = pd.read_parquet(tiny_run / "raw/twin_truth/s00/paddles.parquet")
    rows = paddle_rows(measured, truth)
    assert len(rows) == 4 and not _failed(rows), rows
    assert 0.9 < measured["valid"].mean() < 1.0  # the twin's dropouts show as gaps, not invented poses
    assert measured.loc[~measured["valid"], "px"].isna().all()


def test_every_perception_figure_meets_its_threshold(tiny_run):
    """Each camera's ball (multi-view: what triangulation uses): recall >= 99 %, median < 1 px, false < 0.5 %;
    3D ball < 5 mm; joints < 7.5 cm; the rest. A camera's own detector alone is held to the same median
    and false-detection bars, its recall only reported: in the twin's club room one camera alone misses
    up to 3 % of the visible balls (the tiny run of 2026-12-07: 97.04 / 99.04 / 98.47 %, mostly the ball
    dribbling over the net after a rally, refused as slow), which the other cameras' views give back
    (test below)."""
    table = pd.read_csv(tiny_run / "reports/tables/perception_accuracy.csv")
    # 3 cameras x 2 calibration rows; then 3 cameras x 3 detection rows, single-view and multi-view, + ball
    # + joints + 4 paddle rows
    assert len(table) == 6 + 24
    one_view_recall = table["quantity"].str.endswith("one-view ball recall (visible frames)")
    assert one_view_recall.sum() == 3
    held = table[~one_view_recall]
    assert held["ok"].all(), held[~held["ok"]].to_string()


def test_each_cameras_ball_after_the_views_agreement_is_no_worse_and_makes_the_3d_ball(tiny_run):
    """interim/ball_views against the twin's truth: per camera, recall at least the camera's own detector's
    and false detections at most its own, each within 0.05 points (the tiny run of 2026-12-07, the
    colour method: the same, recall 99.84 / 100 / 99.79 %, false 0 / 0 / 0.01 %); the 3D
    ball's points in flight triangulate from exactly these views (the same points, every view used)."""
    cams, _ = load_cameras(tiny_run / "interim" / "calibration" / "cameras.json")
    views = [read_table(tiny_run / "interim" / "ball_views" / "s00" / f"{c.name}.parquet", DETECTIONS)
             for c in cams]
    for cam, view in zip(cams, views, strict=True):
        truth2d = read_table(tiny_run / "raw" / "twin_truth" / "s00" / f"{cam.name}_ball2d.parquet",
                             truth.BALL2D)
        own = read_table(tiny_run / "interim" / "detections" / "s00" / f"{cam.name}.parquet", DETECTIONS)
        single, multi = (detection_rows(cam.name, table, truth2d) for table in (own, view))
        assert multi[0]["value"] >= single[0]["value"] - 0.05 and multi[0]["ok"], (single, multi)
        assert multi[2]["value"] <= single[2]["value"] + 0.05 and multi[2]["ok"], (single, multi)
    ball = read_table(tiny_run / "interim" / "ball3d" / "s00.parquet", BALL3D)
    px = np.stack([np.where(v["detected"].to_numpy()[:, None], v[["u", "v"]].to_numpy(), np.nan)
                   for v in views], axis=1)
    share = schema_defaults(ROOT / "config" / "schema.yaml")["perception"]["max_reproj_share"]
    again = triangulate_robust(cams, px, reprojection_gate_px(cams, share))
    kept = ball["x"].notna().to_numpy()
    assert kept.mean() > 0.5
    np.testing.assert_allclose(again["points"][kept], ball[["x", "y", "z"]].to_numpy()[kept], atol=1e-9)
    np.testing.assert_array_equal(again["n_views"][kept], ball["n_views"].to_numpy()[kept])
    np.testing.assert_array_equal(again["n_views"][kept], np.isfinite(px[kept]).all(axis=2).sum(axis=1))
