"""The perception stages' artifact layouts (light: no stage code, so readers do not hash the stages)."""

from pingpong.common.artifacts import Schema
from pingpong.frames import MODEL_JOINT_IDS, ROT_COLUMNS

CAMERAS = Schema("cameras", 1)  # interim/calibration/cameras.json
DETECTIONS = Schema("detections", 1, ("time_ns", "u", "v", "area_px", "detected", "decode_ok"))
PADDLE = Schema("paddle", 1, ("time_ns", "player", "px", "py", "pz", *ROT_COLUMNS, "valid"))
MODEL_JOINT_COLUMNS = tuple(f"j{j:02d}_{q}" for j in MODEL_JOINT_IDS for q in ("u", "v", "conf"))
# one row per (frame, person) of a camera: person is its tracklet id, -1 on a frame with nobody
POSE2D = Schema("pose2d", 2, ("time_ns", "person", *MODEL_JOINT_COLUMNS))
BALL3D = Schema("ball3d", 1, ("time_ns", "x", "y", "z", "n_views", "reproj_rms_px"))
POSE3D_JOINT_COLUMNS = tuple(f"j{j:02d}_{q}" for j in MODEL_JOINT_IDS for q in ("x", "y", "z", "n"))
POSE3D = Schema("pose3d", 1, ("time_ns", "player", *POSE3D_JOINT_COLUMNS))
SYNC = Schema("camera_sync", 1, ("camera", "frames", "rate_hz", "first_ns", "last_ns", "dropped_frames",
                                 "non_increasing"))  # interim/sync/{session}.parquet, one row per camera
