"""A session's tables as per-frame arrays: frame times, one player's columns, a paddle, gaps and runs.

Every table here is put on the ball3d table's frames (the 100 Hz camera clock, one row per frame).
"""

import numpy as np
import pandas as pd

from pingpong.frames import MODEL_JOINTS, ROT_COLUMNS
from pingpong.perception.schemas import joint_columns

PLAYER_END = {"near": "+y", "far": "-y"}  # the end of the table each player stands at
OPPONENT_END = {"near": "-y", "far": "+y"}
PLAYER_SIGN = {"near": 1.0, "far": -1.0}
JOINT_XYZ = list(joint_columns(MODEL_JOINTS, "xyz"))  # the pose3d table's model joints
JOINT_VIEWS = list(joint_columns(MODEL_JOINTS, ("views",)))
PADDLE_VALUES = ["px", "py", "pz", *ROT_COLUMNS]


def frame_seconds(time_ns) -> np.ndarray:
    """Frame times in s from the first frame (float64 keeps the session's ~1e18 ns epoch exact this way)."""
    time_ns = np.asarray(time_ns, np.int64)
    return (time_ns - time_ns[0]) * 1e-9


def per_player(table: pd.DataFrame, player: str, columns, time_ns: np.ndarray) -> np.ndarray:
    """One player's columns (T, len(columns)) on the frames time_ns; NaN on frames the table lacks."""
    rows = table[table["player"] == player].drop_duplicates("time_ns").set_index("time_ns")
    return rows.reindex(time_ns)[list(columns)].to_numpy(float, copy=True)


def paddle_arrays(paddle: pd.DataFrame, player: str, time_ns: np.ndarray) -> np.ndarray:
    """A player's paddle (T, 12): position, rotation row-major; NaN where OptiTrack had a gap."""
    values = per_player(paddle, player, PADDLE_VALUES, time_ns)
    valid = per_player(paddle.assign(valid=paddle["valid"].astype(float)), player, ["valid"], time_ns)[:, 0]
    values[~(valid > 0)] = np.nan
    return values


def fill_short_gaps(values: np.ndarray, max_gap: int) -> np.ndarray:
    """Columns of values (T, D) linearly interpolated across NaN runs of at most max_gap samples."""
    out = values.copy()
    good = np.isfinite(values).all(axis=1)
    if good.sum() < 2:
        return out
    short = np.zeros(len(values), bool)
    for start, stop in zip(*runs(~good), strict=True):
        short[start:stop] = stop - start <= max_gap and start > 0 and stop < len(values)
    k = np.arange(len(values))
    for d in range(values.shape[1]):
        out[short, d] = np.interp(k[short], k[good], values[good, d])
    return out


def runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Starts and stops ([start, stop)) of the True runs in a boolean mask."""
    edges = np.diff(np.concatenate([[0], np.asarray(mask, np.int8), [0]]))
    return np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
