"""The perception stages' artifact layouts (light: no stage code, so readers do not hash the stages)."""

from pingpong.common.artifacts import Schema
from pingpong.frames import MODEL_JOINTS, ROT_COLUMNS


def joint_columns(joints, values) -> tuple[str, ...]:
    """Columns named by joint (as `openpose_json.pose_keypoints` names it) and value, joint-major:
    RShoulder_x, RShoulder_y, ..."""
    return tuple(f"{joint}_{value}" for joint in joints for value in values)


def table_joints(columns, value: str) -> tuple[str, ...]:
    """The joints of a pose table's columns, in column order: those with a `{joint}_{value}` column."""
    suffix = f"_{value}"
    return tuple(c[:-len(suffix)] for c in columns if c.endswith(suffix))


CAMERAS = Schema("cameras", 1)  # interim/calibration/cameras.json
DETECTIONS = Schema("detections", 1, ("time_ns", "u", "v", "area_px", "detected", "decode_ok"))
# every ball candidate the detector weighed, one row each (interim/ball_candidates/{session}/{cam}.parquet):
# pixel centre, blob area, the detector's score (higher: more ball-like), whether it is the frame's detection,
# and why (kept, or the test that refused it: e.g. static, slow, off_track, colour, size, lone)
BALL_CANDIDATES = Schema("ball_candidates", 1, ("time_ns", "u", "v", "area_px", "score", "kept", "reason"))
PADDLE = Schema("paddle", 1, ("time_ns", "player", "px", "py", "pz", *ROT_COLUMNS, "valid"))
POSE2D_VALUES = ("u", "v", "conf")  # distorted pixels, OpenPose's confidence
MODEL_JOINT_COLUMNS = joint_columns(MODEL_JOINTS, POSE2D_VALUES)
# one row per (frame, person) of a camera: person is its tracklet id, -1 on a frame with nobody; every
# keypoint of the declared model (BODY_25's name where BODY_25 has the joint), the 8 model joints among them
POSE2D = Schema("pose2d", 4, ("time_ns", "person", *MODEL_JOINT_COLUMNS))
BALL3D = Schema("ball3d", 1, ("time_ns", "x", "y", "z", "n_views", "reproj_rms_px"))
# per joint: position (m, the calibration's world), the views used, their RMS reprojection error (px)
POSE3D_VALUES = ("x", "y", "z", "views", "reproj_px")
POSE3D_JOINT_COLUMNS = joint_columns(MODEL_JOINTS, POSE3D_VALUES)
POSE3D = Schema("pose3d", 3, ("time_ns", "player", *POSE3D_JOINT_COLUMNS))
SYNC = Schema("camera_sync", 1, ("camera", "frames", "rate_hz", "first_ns", "last_ns", "dropped_frames",
                                 "non_increasing"))  # interim/sync/{session}.parquet, one row per camera
