"""Perception against the twin's truth: one row per measured quantity, with the threshold it must meet.

Only twin runs have truth; the rows are what the perception tests assert and what
reports/tables/perception_accuracy.md shows.
"""

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation, Slerp

from pingpong.common.camera import Camera
from pingpong.frames import BODY25, ROT_COLUMNS
from pingpong.reports.tables import threshold_row as _row


def calibration_rows(calibrated: list[Camera], reports: list[dict], truth: list[Camera]) -> list[dict]:
    """Reprojection RMS and camera-centre error per camera (centres compared by name)."""
    true_by_name = {c.name: c for c in truth}
    rows = []
    for cam, rep in zip(calibrated, reports, strict=True):
        rms = max(rep["intrinsics_rms_px"], rep["extrinsics_rms_px"])
        rows.append(_row(f"{cam.name} reprojection RMS", rms, "px", 0.5))
        err = np.linalg.norm(cam.center - true_by_name[cam.name].center)
        rows.append(_row(f"{cam.name} centre error", 100 * err, "cm", 1.0))
    return rows


def paddle_rows(measured: pd.DataFrame, truth: pd.DataFrame) -> list[dict]:
    """Median position (mm) and rotation (deg) error of the valid resampled paddle poses."""
    rows = []
    for player, m in measured[measured["valid"]].groupby("player"):
        t = truth[truth["player"] == player]
        tt, mt = t["time_ns"].to_numpy(), m["time_ns"].to_numpy()
        true_pos = np.column_stack([np.interp(mt, tt, t[c].to_numpy()) for c in ("px", "py", "pz")])
        pos_err = np.linalg.norm(m[["px", "py", "pz"]].to_numpy() - true_pos, axis=1)
        rot_cols = list(ROT_COLUMNS)
        true_rot = Slerp(tt, Rotation.from_matrix(t[rot_cols].to_numpy().reshape(-1, 3, 3)))(mt)
        ang = (true_rot.inv() * Rotation.from_matrix(m[rot_cols].to_numpy().reshape(-1, 3, 3))).magnitude()
        rows.append(_row(f"paddle {player} position error (median)", 1e3 * np.median(pos_err), "mm", 2.0))
        rows.append(_row(f"paddle {player} rotation error (median)", np.degrees(np.median(ang)), "deg", 1.0))
    return rows


VISIBLE = 0.5  # a ball counts as visible when at least half of its blurred image shows
FALSE_PX = 5.0  # a detection is false unless some of the ball shows within this of its centre


def detection_rows(cam: str, detections: pd.DataFrame, truth2d: pd.DataFrame) -> list[dict]:
    """Recall on visible frames (a detection within FALSE_PX of the ball's centre: a detection elsewhere in
    such a frame is false, not found), median centre error (px) and the share of false detections."""
    d = detections.merge(truth2d, on="time_ns", how="inner")
    visible = d["visibility"].to_numpy() >= VISIBLE
    err = np.hypot(d["u_x"] - d["u_y"], d["v_x"] - d["v_y"]).to_numpy()
    found = d["detected"].to_numpy()
    on_ball = found & (d["visibility"].to_numpy() > 0) & (err <= FALSE_PX)  # NaN err: no ball at all
    false = found & ~on_ball
    return [_row(f"{cam} ball recall (visible frames)", 100 * on_ball[visible].mean(), "%", 99.0, "at least"),
            _row(f"{cam} ball centre error (median)", float(np.median(err[found & visible])), "px", 1.0),
            _row(f"{cam} false detections", 100 * false.mean(), "% of frames", 0.5)]


def ball3d_rows(ball3d: pd.DataFrame, true_positions: np.ndarray) -> list[dict]:
    err = np.linalg.norm(ball3d[["x", "y", "z"]].to_numpy() - true_positions, axis=1)
    return [_row("3D ball error (median)", 1e3 * float(np.nanmedian(err)), "mm", 5.0)]


def pose3d_rows(pose3d: pd.DataFrame, people: pd.DataFrame, joint_ids) -> list[dict]:
    errors = []
    for player in ("near", "far"):
        est = pose3d[pose3d["player"] == player].set_index("time_ns")
        true = people[people["person"] == player].set_index("time_ns").loc[est.index]
        for j in joint_ids:
            true_xyz = true[[f"j{j:02d}_{a}" for a in "xyz"]].to_numpy()  # the truth's: by BODY_25 index
            est_xyz = est[[f"{BODY25[j]}_{a}" for a in "xyz"]].to_numpy()  # pose3d's: by name
            errors.append(np.linalg.norm(est_xyz - true_xyz, axis=1))
    # the twin's keypoints err as a detector's (twin.keypoint_errors); OpenPose's multi-camera joint centres
    # lie 30-50 mm off marker-based ones at the hip and knee (Needham et al. 2021, Sci Rep, abstract):
    # 1.5x that upper figure (the tiny run: 5.3 cm; 1.3 cm before issue 41's detector errors)
    return [_row("8-joint 3D error (median)", 100 * float(np.nanmedian(np.concatenate(errors))), "cm", 7.5)]
