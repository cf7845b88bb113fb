"""The table frame, the lab's fixed dimensions, physical constants and the joint sets
(docs/architecture.md, "Frames and units").

Table frame: origin at the centre of the table surface, x across the width, y along the
length, z up. All values in SI units (metres, seconds, kilograms).
"""

import numpy as np

TABLE_LENGTH = 2.74  # ITTF regulation table, m
TABLE_WIDTH = 1.525
TABLE_HALF_LENGTH = TABLE_LENGTH / 2  # 1.37
TABLE_HALF_WIDTH = TABLE_WIDTH / 2  # 0.7625
NET_HEIGHT = 0.1525  # above the table surface
NET_OVERHANG = 0.1525  # the net reaches this far beyond each side line

BALL_RADIUS = 0.020  # 40 mm ball
BALL_MASS = 0.0027  # kg
GRAVITY = 9.81  # m/s^2, along -z

CAMERA_FPS = 100.0  # the master clock
FRAME_NS = 10_000_000  # one camera frame in ns

STRIKE_Y = -1.40  # the robot's strike line, m
REGION_EDGE_X = 0.25  # left < -0.25 <= centre <= 0.25 < right
N_PRED_FRAMES = 30  # the model predicts at each frame from 30 before the hit to the hit itself (31 frames)

# OpenPose BODY_25 keypoint order.
BODY25 = (
    "Nose", "Neck", "RShoulder", "RElbow", "RWrist", "LShoulder", "LElbow", "LWrist",
    "MidHip", "RHip", "RKnee", "RAnkle", "LHip", "LKnee", "LAnkle", "REye", "LEye",
    "REar", "LEar", "LBigToe", "LSmallToe", "LHeel", "RBigToe", "RSmallToe", "RHeel",
)
MODEL_JOINTS = ("RShoulder", "RElbow", "RWrist", "LShoulder", "LElbow", "LWrist", "RHip", "LHip")
MODEL_JOINT_IDS = tuple(BODY25.index(j) for j in MODEL_JOINTS)
# the model joints' skeleton, as index pairs into MODEL_JOINTS: arms, shoulders, sides, hips
MODEL_BONES = ((0, 1), (1, 2), (3, 4), (4, 5), (0, 3), (0, 6), (3, 7), (6, 7))
N_JOINT_VALUES = 3 * len(MODEL_JOINTS)  # the first 24 of a frame's values
N_INPUT = N_JOINT_VALUES + 3 + 9 + 3  # 39 values per frame
ROT_COLUMNS = tuple(f"r{i}{j}" for i in range(3) for j in range(3))  # a rotation matrix, row-major


def region_of(strike_x: np.ndarray) -> np.ndarray:
    """Region label ('left', 'centre', 'right') of strike-point x values (m)."""
    x = np.asarray(strike_x, dtype=float)
    return np.where(x < -REGION_EDGE_X, "left", np.where(x > REGION_EDGE_X, "right", "centre"))
