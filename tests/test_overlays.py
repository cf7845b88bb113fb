"""QA overlays: frames chosen where the ball was triangulated, the ball and joints drawn where the
calibration projects them, one labelled panel per frame."""

import cv2
import numpy as np
import pandas as pd

from pingpong.common.camera import Camera, look_at
from pingpong.frames import MODEL_JOINTS
from pingpong.io.camera_streams import CameraFrame
from pingpong.perception.schemas import POSE3D_JOINT_COLUMNS
from pingpong.reports.overlays import BALL_BGR, PLAYER_BGR, draw_overlay, overlay_times, session_overlay


def camera() -> Camera:
    R, t = look_at(np.array([0.0, 4.0, 2.0]), np.zeros(3))
    K = np.array([[500.0, 0, 240], [0, 500.0, 180], [0, 0, 1]])
    return Camera("cam0", K, np.zeros(5), R, t, 480, 360)


def tables(n=50):
    time_ns = 10_000_000 * np.arange(n, dtype=np.int64)
    ball = pd.DataFrame({"time_ns": time_ns, "x": 0.1, "y": 0.0, "z": 0.3, "n_views": 2,
                         "reproj_rms_px": 0.1})
    ball.loc[:9, ["x", "y", "z"]] = np.nan  # the ball unseen in the first 10 frames
    joints = dict(zip(POSE3D_JOINT_COLUMNS, np.tile((0.3, 1.5, 1.0, 2, 0.5), len(MODEL_JOINTS)), strict=True))
    pose = pd.DataFrame({"time_ns": time_ns, "player": "near", **joints})
    detections = pd.DataFrame({"time_ns": time_ns, "u": 250.0, "v": 170.0, "area_px": 20, "detected": True,
                               "decode_ok": True})
    return ball, pose, detections


def test_frames_are_spread_over_the_triangulated_ball():
    ball, _, _ = tables()
    chosen = overlay_times(ball, 4)
    assert len(chosen) == 4 and chosen[0] == ball["time_ns"][10] and chosen[-1] == ball["time_ns"].iloc[-1]


def test_the_ball_and_joints_are_drawn_where_the_camera_projects_them():
    cam, image = camera(), np.zeros((360, 480, 3), np.uint8)
    ball = np.array([0.1, 0.0, 0.3])
    joints = {"far": np.tile([[-0.3, -1.5, 1.0]], (8, 1))}
    out = draw_overlay(image, cam, ball, np.array([np.nan, np.nan]), joints)
    u, v = np.round(cam.project(ball)[0]).astype(int)
    ring = out[v - 8:v + 9, u - 8:u + 9]
    green = np.abs(ring.astype(int) - BALL_BGR).sum(axis=-1) < 120  # anti-aliased: near the colour
    assert green.any() and not green[8, 8]  # a circle around the point, not a dot on it
    ju, jv = np.round(cam.project(joints["far"][:1])[0]).astype(int)
    assert (np.abs(out[jv - 3:jv + 4, ju - 3:ju + 4].astype(int) - PLAYER_BGR["far"]).sum(axis=-1) < 60).any()
    assert image.max() == 0  # the input is left as it was


def test_a_session_overlay_is_one_labelled_panel_per_frame():
    ball, pose, detections = tables()
    jpeg = cv2.imencode(".jpg", np.full((360, 480, 3), 40, np.uint8))[1].tobytes()
    frames = [CameraFrame(int(t), jpeg) for t in ball["time_ns"]]
    grid = session_overlay(iter(frames), camera(), ball, pose, detections, 4, "s00 cam0")
    assert grid.shape == (2 * 360, 2 * 480, 3)
