"""QA overlays: the triangulated ball and joints reprojected onto a few frames of one camera.

What a person checks first on a new recording: do the 3D points land on the ball and the players in
every view? Each panel is one frame with the 3D ball (circle, its reprojection) beside the camera's own
2D detection (cross), and both players' 8 model joints with their skeleton (near: orange, far: cyan).
"""

import logging

import cv2
import numpy as np
import pandas as pd

from pingpong.common.camera import Camera
from pingpong.curation.tracks import JOINT_XYZ
from pingpong.frames import MODEL_BONES

log = logging.getLogger(__name__)
BALL_BGR, DETECTION_BGR = (0, 255, 0), (255, 0, 255)
PLAYER_BGR = {"near": (0, 140, 255), "far": (255, 200, 0)}


def overlay_times(ball3d: pd.DataFrame, n_frames: int) -> np.ndarray:
    """n_frames frame times (ns) spread evenly over the frames where the ball was triangulated."""
    seen = ball3d.loc[ball3d["x"].notna(), "time_ns"].to_numpy(np.int64)
    if len(seen) == 0:
        return seen
    return seen[np.unique(np.linspace(0, len(seen) - 1, n_frames).round().astype(int))]


def _point(image, uv, colour, radius) -> None:
    if np.isfinite(uv).all():
        cv2.circle(image, tuple(int(round(c)) for c in uv), radius, colour, 1, cv2.LINE_AA)


def draw_overlay(image: np.ndarray, camera: Camera, ball_xyz: np.ndarray, detection_uv: np.ndarray,
                 joints_xyz: dict[str, np.ndarray]) -> np.ndarray:
    """A copy of the BGR image with the reprojected ball (3,), the 2D detection (2,) and each player's
    joints (8, 3) drawn; NaN points are left out."""
    out = image.copy()
    scale = max(1, round(out.shape[1] / 480))  # line sizes that stay visible at any resolution
    _point(out, camera.project(ball_xyz)[0], BALL_BGR, 6 * scale)
    if np.isfinite(detection_uv).all():
        u, v = (int(round(c)) for c in detection_uv)
        cv2.drawMarker(out, (u, v), DETECTION_BGR, cv2.MARKER_CROSS, 8 * scale, 1)
    for player, joints in joints_xyz.items():
        uv = camera.project(joints)
        for a, b in MODEL_BONES:
            if np.isfinite(uv[[a, b]]).all():
                cv2.line(out, tuple(np.round(uv[a]).astype(int)), tuple(np.round(uv[b]).astype(int)),
                         PLAYER_BGR[player], scale, cv2.LINE_AA)
        for point in uv:
            _point(out, point, PLAYER_BGR[player], 2 * scale)
    return out


def frame_points(time_ns: int, ball3d: pd.DataFrame, pose3d: pd.DataFrame, detections: pd.DataFrame):
    """(ball (3,), detection (2,), {player: joints (8, 3)}) of one frame; NaN where missing."""
    ball = ball3d.loc[ball3d["time_ns"] == time_ns, ["x", "y", "z"]].to_numpy(float)
    det = detections.loc[detections["time_ns"] == time_ns, ["u", "v"]].to_numpy(float)
    rows = pose3d[pose3d["time_ns"] == time_ns]
    joints = {p: rows.loc[rows["player"] == p, JOINT_XYZ].to_numpy(float).reshape(-1, 3)
              for p in PLAYER_BGR if (rows["player"] == p).any()}
    return (ball[0] if len(ball) else np.full(3, np.nan), det[0] if len(det) else np.full(2, np.nan),
            joints)


def overlay_grid(panels: list[np.ndarray], labels: list[str], columns: int = 2) -> np.ndarray:
    """Panels (same size) in a grid, each labelled in its corner; empty cells black."""
    h, w = panels[0].shape[:2]
    rows = -(-len(panels) // columns)
    grid = np.zeros((rows * h, columns * w, 3), np.uint8)
    for k, (panel, label) in enumerate(zip(panels, labels, strict=True)):
        r, c = divmod(k, columns)
        cell = grid[r * h:(r + 1) * h, c * w:(c + 1) * w]
        cell[:] = panel
        cv2.putText(cell, label, (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
    return grid


def session_overlay(frames, camera: Camera, ball3d: pd.DataFrame, pose3d: pd.DataFrame,
                    detections: pd.DataFrame, n_frames: int, label: str) -> np.ndarray:
    """The overlay grid of one camera's stream (CameraFrame iterator) on n_frames frames with a ball."""
    wanted = set(overlay_times(ball3d, n_frames).tolist())
    panels, labels = [], []
    for frame in frames:
        if frame.time_ns not in wanted:
            continue
        image, reason = frame.decode()
        if image is None:
            log.warning("frame at %d ns does not decode (%s); left out of the overlay", frame.time_ns, reason)
            continue
        panels.append(draw_overlay(image, camera, *frame_points(frame.time_ns, ball3d, pose3d, detections)))
        labels.append(f"{label} t={(frame.time_ns - ball3d['time_ns'].iloc[0]) / 1e9:.2f} s")
        if len(panels) == len(wanted):
            break
    if not panels:
        raise ValueError(f"{label}: none of the {len(wanted)} frames with a triangulated ball decodes")
    return overlay_grid(panels, labels)
