"""Where the twin's OptiTrack world frame lies relative to the table."""

import numpy as np
from scipy.spatial.transform import Rotation

from pingpong.common.rigid import make_transform

# Motive streams y-up: table z (up) becomes OptiTrack y, table y becomes OptiTrack -z.
Y_UP_FROM_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def optitrack_from_table(rng: np.random.Generator) -> np.ndarray:
    """4x4 T_optitrack_from_table: y-up, the ground plane origin on the floor off the table, any yaw."""
    yaw = Rotation.from_euler("z", rng.uniform(-np.pi, np.pi)).as_matrix()
    origin_in_table = np.array([rng.uniform(-2, 2), rng.uniform(-2, 2), -0.76])  # on the floor
    R = Y_UP_FROM_Z_UP @ yaw
    return make_transform(R, -R @ origin_in_table)
