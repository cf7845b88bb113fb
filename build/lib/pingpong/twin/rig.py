"""The lab's camera rig: cameras behind and above both table ends, looking at the table.

Intrinsics follow a real machine-vision camera scaled to the chosen resolution (the paper's
were 1440x1080): the focal length is a fixed fraction of the image width (about 57 deg of
horizontal field of view), so the scene looks the same at any resolution. Lens distortion is
barrel (k1 < 0) with k2 chosen so that the radial map is monotonic over the whole plane, which
keeps every image pixel a single ray (needed by the inverse-map renderer).
"""

import numpy as np
from scipy.spatial.transform import Rotation

from pingpong.common.camera import Camera, look_at

FLOOR_Z = -0.76  # table-frame height of the floor (the table top is 76 cm high), m


def camera_azimuths(n_cameras: int) -> np.ndarray:
    """Horizontal directions (rad, from table +x) of the cameras: half behind each end, at the sides."""
    n_pos = (n_cameras + 1) // 2
    pos_end = np.linspace(np.radians(60), np.radians(120), n_pos) if n_pos > 1 else np.array([np.pi / 2])
    n_neg = n_cameras - n_pos
    neg_end = np.linspace(np.radians(240), np.radians(300), n_neg) if n_neg > 1 else np.array([1.5 * np.pi])
    return np.concatenate([pos_end, neg_end[:n_neg]])


def lens_distortion(rng: np.random.Generator) -> np.ndarray:
    """(k1, k2, p1, p2, k3): barrel k1, k2 >= 9 k1^2 / 20 so 1 + 3 k1 r^2 + 5 k2 r^4 > 0 for all r."""
    k1 = rng.uniform(-0.25, -0.10)
    k2 = 9 * k1**2 / 20 * rng.uniform(1.05, 1.6)
    p1, p2 = rng.normal(0.0, 3e-4, size=2)
    return np.array([k1, k2, p1, p2, 0.0])


def make_rig(rng: np.random.Generator, n_cameras: int = 4, width: int = 480, height: int = 360,
             distance: tuple[float, float] = (3.6, 4.2), floor_height: tuple[float, float] = (2.5, 3.0),
             focal_fraction: tuple[float, float] = (0.86, 0.96)) -> list[Camera]:
    """`n_cameras` cameras named cam0.. around the table (table frame, OpenCV conventions).

    distance: horizontal distance from the table centre (m); floor_height: height above the
    floor (m); focal_fraction: focal length as a fraction of the image width.
    """
    cameras = []
    for i, azimuth in enumerate(camera_azimuths(n_cameras)):
        radius = rng.uniform(*distance)
        eye = np.array([radius * np.cos(azimuth), radius * np.sin(azimuth),
                        rng.uniform(*floor_height) + FLOOR_Z])
        target = np.array([0.0, 0.0, 0.15]) + rng.normal(0.0, [0.08, 0.08, 0.05])
        R, _ = look_at(eye, target)
        roll = Rotation.from_rotvec(R[2] * np.radians(rng.normal(0.0, 1.0))).as_matrix()
        R = R @ roll.T  # a slightly rolled mount
        f = width * rng.uniform(*focal_fraction)
        K = np.array([[f, 0.0, width / 2 + rng.normal(0.0, 0.01 * width)],
                      [0.0, f * (1 + rng.normal(0.0, 1e-3)), height / 2 + rng.normal(0.0, 0.01 * height)],
                      [0.0, 0.0, 1.0]])
        cameras.append(Camera(name=f"cam{i}", K=K, dist=lens_distortion(rng), R=R, t=-R @ eye,
                              width=width, height=height))
    return cameras
