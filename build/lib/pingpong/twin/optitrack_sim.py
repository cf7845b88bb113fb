"""The twin's OptiTrack: paddle rigid bodies and table markers as Motive would stream them.

- World frame: Motive's, y up. `table_to_optitrack(rng)` draws where the table stands in it:
  p_ot = R p_table + t, with table z -> OptiTrack y, a random yaw about y and the origin on the
  floor somewhere near the table (the twin truth records R, t).
- Paddles `paddle_{name}`: the rigid body's frame is the paddle frame of twin.render (origin at
  the blade centre, z out of the red side) at `rate_hz` (default 240), with per-sample noise
  (0.3 mm per axis, 0.1 deg rotation) and dropouts (gaps of a few samples; missing messages).
- Table markers `table_marker_{i}`: the four patterns.TABLE_MARKERS (table corners), each a
  position-only rigid body (identity orientation) at `marker_rate_hz` (default 10 Hz), same noise.
- Clock: OptiTrack and cameras are hardware-synchronised to one epoch; log_time = camera-clock
  time + `clock_offset_ns` (default 0, recorded in the twin truth).
"""

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from pingpong.common.patterns import TABLE_MARKERS
from pingpong.io.mcap_io import OptitrackWriter
from pingpong.twin.rig import FLOOR_Z

TABLE_Z_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # table x, y, z -> x, -z, y


def table_to_optitrack(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) with p_optitrack = R @ p_table + t: y up, random yaw, origin on the floor within 2 m."""
    yaw = Rotation.from_rotvec([0.0, rng.uniform(-np.pi, np.pi), 0.0]).as_matrix()
    R = yaw @ TABLE_Z_TO_Y_UP
    t = np.array([rng.uniform(-2.0, 2.0), -FLOOR_Z, rng.uniform(-2.0, 2.0)])
    return R, t


def dropout_mask(n: int, rng: np.random.Generator, gap_rate: float = 0.002,
                 mean_gap: float = 8.0) -> np.ndarray:
    """(n,) bool, True where a sample is delivered: gaps start with prob gap_rate, geometric lengths."""
    keep = np.ones(n, bool)
    for start in np.flatnonzero(rng.random(n) < gap_rate):
        keep[start:start + rng.geometric(1.0 / mean_gap)] = False
    return keep


def noisy_poses(positions: np.ndarray, rotations: np.ndarray, rng: np.random.Generator,
                noise_m: float = 0.0003, noise_rad: float = np.radians(0.1)) -> tuple[np.ndarray, np.ndarray]:
    """Positions (N, 3) and quaternions xyzw (N, 4) with measurement noise added."""
    n = len(positions)
    noisy_p = positions + rng.normal(0.0, noise_m, (n, 3))
    jitter = Rotation.from_rotvec(rng.normal(0.0, noise_rad, (n, 3)))
    quats = (jitter * Rotation.from_matrix(rotations)).as_quat()  # scipy: xyzw
    return noisy_p, quats


def write_optitrack_session(path: str | Path, times_ns: np.ndarray,
                            paddles: dict[str, tuple[np.ndarray, np.ndarray]],
                            table_to_ot: tuple[np.ndarray, np.ndarray], rng: np.random.Generator,
                            clock_offset_ns: int = 0, marker_rate_hz: float = 10.0) -> None:
    """Write `optitrack.mcap` from true paddle poses in the table frame.

    times_ns: (N,) camera-clock sample times at the OptiTrack rate; paddles: {name: (positions (N, 3),
    rotations (N, 3, 3))} in the table frame at those times.
    """
    R, t = table_to_ot
    times_ns = np.asarray(times_ns, np.int64)
    streams = []  # (time, body, position, quaternion) rows of every body, merged by time below
    for name, (positions, rotations) in paddles.items():
        p_ot = np.asarray(positions) @ R.T + t
        rot_ot = R @ np.asarray(rotations)
        p, q = noisy_poses(p_ot, rot_ot, rng)
        keep = dropout_mask(len(times_ns), rng)
        streams += [(times_ns[i], f"paddle_{name}", p[i], q[i]) for i in np.flatnonzero(keep)]
    marker_times = np.arange(times_ns[0], times_ns[-1] + 1, int(round(1e9 / marker_rate_hz)), dtype=np.int64)
    for index, marker in enumerate(TABLE_MARKERS):
        p = R @ marker + t + rng.normal(0.0, 0.0003, (len(marker_times), 3))
        keep = dropout_mask(len(marker_times), rng, gap_rate=0.01, mean_gap=2.0)
        streams += [(marker_times[i], f"table_marker_{index}", p[i], np.array([0.0, 0.0, 0.0, 1.0]))
                    for i in np.flatnonzero(keep)]
    streams.sort(key=lambda row: (row[0], row[1]))
    with OptitrackWriter(path) as writer:
        for time_ns, body, position, quat in streams:
            writer.add(body, int(time_ns) + clock_offset_ns, position, quat)
