"""pose3d's joints named by the declared model's keypoints, and its view policies (config
perception.pose_view_policy): every view within the gate (the default) or Pose2Sim's mean reprojection error
under a threshold. Synthetic projections of one player on a 4-camera twin rig (table frame, 480x360)."""

import numpy as np
import pandas as pd
import pytest

from pingpong.frames import MODEL_JOINTS
from pingpong.perception.pose3d import pose3d_table
from pingpong.perception.scene import default_players_scene
from pingpong.perception.schemas import POSE2D, POSE2D_VALUES, POSE3D, POSE3D_VALUES, joint_columns
from pingpong.twin.rig import make_rig

N_FRAMES = 20
# a standing player's joints about the mid-hip (m): the 8 model joints, two more of BODY_25 and BODY_25B's
# HeadTop, which BODY_25 has no name for
JOINTS = (*MODEL_JOINTS, "Nose", "RKnee", "HeadTop")
BODY = np.array([[-0.2, 0, 0.5], [-0.3, 0, 0.25], [-0.3, 0.1, 0.0], [0.2, 0, 0.5], [0.3, 0, 0.25],
                 [0.3, 0.1, 0.0], [-0.1, 0, 0.0], [0.1, 0, 0.0], [0.0, 0.05, 0.75], [-0.1, 0.05, -0.45],
                 [0.0, 0.03, 0.85]])
NEAR = np.array([0.2, 2.3, -0.1])
BAD_CAMERA = 3


@pytest.fixture(scope="module")
def rig():
    return make_rig(np.random.default_rng(1), 4, 480, 360)


def _tables(cameras, offset_px: dict[str, float], rng) -> list[pd.DataFrame]:
    """Each camera's POSE2D table of the near player (JOINTS, 0.3 px noise); offset_px moves a joint's
    view in BAD_CAMERA by that many pixels along u."""
    tables = []
    for c, cam in enumerate(cameras):
        px = cam.project(NEAR + BODY) + rng.normal(0, 0.3, (N_FRAMES, len(JOINTS), 2))
        if c == BAD_CAMERA:
            for name, offset in offset_px.items():
                px[:, JOINTS.index(name), 0] += offset
        values = np.concatenate([px, np.full((N_FRAMES, len(JOINTS), 1), 0.9)], axis=2)
        table = pd.DataFrame(values.reshape(N_FRAMES, -1), columns=list(joint_columns(JOINTS, POSE2D_VALUES)))
        table.insert(0, "person", 0)
        table.insert(0, "time_ns", 10_000_000 * np.arange(N_FRAMES, dtype=np.int64))
        tables.append(table)
    return tables


def _pose(cameras, tables, policy="all_within_gate", threshold_px=15.0) -> pd.DataFrame:
    pose, _ = pose3d_table(cameras, tables, default_players_scene(), 0.02, 0.005, 4.0, False, 2, policy,
                           threshold_px)
    return pose[pose["player"] == "near"]


def _error_m(pose: pd.DataFrame, name: str) -> np.ndarray:
    return np.linalg.norm(pose[[f"{name}_{a}" for a in "xyz"]].to_numpy() - (NEAR + BODY[JOINTS.index(name)]),
                          axis=1)


def test_columns_are_named_by_the_tables_joints(rig):
    """Every keypoint of the POSE2D tables is triangulated, its columns named by the joint: position, views
    used, their reprojection error (px); the pose3d schema's columns (the 8 model joints') among them."""
    tables = _tables(rig, {}, np.random.default_rng(0))
    assert set(POSE2D.columns) <= set(tables[0].columns)
    pose = _pose(rig, tables)
    assert list(pose.columns) == ["time_ns", "player", *joint_columns(JOINTS, POSE3D_VALUES)]
    assert set(POSE3D.columns) <= set(pose.columns)
    for name in JOINTS:
        assert (pose[f"{name}_views"] == 4).all()
        assert (pose[f"{name}_reproj_px"] < 1.5).all()
        assert _error_m(pose, name).max() < 0.01


def test_the_threshold_policy_drops_a_bad_view(rig):
    """A wrist 60 px off in one view: the mean error of all four views exceeds 15 px, so Pose2Sim's policy
    drops that view (as the gate does) and the wrist lies where the three good views put it."""
    tables = _tables(rig, {"RWrist": 60.0}, np.random.default_rng(0))
    for policy in ("mean_error_under", "all_within_gate"):
        pose = _pose(rig, tables, policy)
        assert (pose["RWrist_views"] == 3).all(), policy
        assert _error_m(pose, "RWrist").max() < 0.01
        assert (pose["RShoulder_views"] == 4).all()
    everything = _pose(rig, tables, "mean_error_under", threshold_px=1e3)  # a threshold that keeps every view
    assert (everything["RWrist_views"] == 4).all() and _error_m(everything, "RWrist").min() > 0.02


def test_the_threshold_policy_keeps_a_view_within_its_threshold(rig):
    """A knee 8 px off in one view: beyond the gate (3 px at 480x360), within Pose2Sim's 15 px mean: the
    gate drops the view, the threshold policy keeps all four and the knee moves off by the view's pull."""
    tables = _tables(rig, {"RKnee": 8.0}, np.random.default_rng(0))
    gated, threshold = _pose(rig, tables), _pose(rig, tables, "mean_error_under")
    assert (gated["RKnee_views"] == 3).all() and (threshold["RKnee_views"] == 4).all()
    assert (threshold["RKnee_reproj_px"] > gated["RKnee_reproj_px"]).all()
    assert np.median(_error_m(threshold, "RKnee")) > np.median(_error_m(gated, "RKnee"))


def test_an_unknown_policy_is_refused(rig):
    with pytest.raises(ValueError, match="view policy must be one of"):
        _pose(rig, _tables(rig, {}, np.random.default_rng(0)), "best_three")
