"""The measured post-hit flights the simulated robot plays against, and the predictions it anticipates on.

A flight is the filtered 3D ball (interim/filtered/{session}_ball.parquet) from the hit on, in seconds from
the hit, mirrored like the dataset's input for a 'far' hitter (curation.labels.mirror_points) so that every
ball travels towards the robot at y = STRIKE_Y. It is cut one sample past its first crossing of the strike
line: later samples (the robot's side's return) are not the same flight.
"""

import numpy as np
import pandas as pd

from pingpong.curation.labels import mirror_points
from pingpong.frames import STRIKE_Y

HIT_KEYS = ["session", "rally", "hit"]


def hit_flight(ball: pd.DataFrame, t_hit_ns: int, hitter: str, max_duration_s: float = 1.5,
               strike_y: float = STRIKE_Y) -> tuple[np.ndarray, np.ndarray]:
    """(times (N,) s from the hit, positions (N, 3) m) of one hit's flight; frames without a ball left out."""
    time_ns = ball["time_ns"].to_numpy(np.int64)
    rows = (time_ns >= t_hit_ns) & (time_ns <= t_hit_ns + int(max_duration_s * 1e9))
    positions = ball.loc[rows, ["x", "y", "z"]].to_numpy(float)
    times = (time_ns[rows] - t_hit_ns) / 1e9
    seen = np.isfinite(positions).all(axis=1)
    times, positions = times[seen], positions[seen]
    if hitter == "far":
        positions = mirror_points(positions)
    beyond = np.flatnonzero(positions[:, 1] <= strike_y)
    if len(beyond):
        times, positions = times[:beyond[0] + 1], positions[:beyond[0] + 1]
    return times, positions


def hit_flights(hits: pd.DataFrame, balls: dict[str, pd.DataFrame], max_duration_s: float = 1.5) -> list:
    """hit_flight of every row of a DATASET table (session, t_hit_ns, hitter), in row order."""
    return [hit_flight(balls[h.session], int(h.t_hit_ns), h.hitter, max_duration_s)
            for h in hits.itertuples(index=False)]


def prediction_series(predictions: pd.DataFrame, hits: pd.DataFrame, value: str) -> list[tuple[np.ndarray,
                                                                                             np.ndarray]]:
    """Per hit (rows of `hits`): (frames (F,) negative, values (F,)) of a per-frame prediction column.

    predictions: one row per (session, rally, hit, frames_before_hit) holding `value` (e.g. strike_x_pred
    of PREDICTIONS, or uncertainty of an uncertainty table); frames are -frames_before_hit in time order.
    A hit without rows gets empty arrays.
    """
    grouped = {key: rows for key, rows in predictions.groupby(HIT_KEYS, sort=False)}
    out = []
    for key in hits[HIT_KEYS].itertuples(index=False, name=None):
        rows = grouped.get(tuple(key))
        if rows is None:
            out.append((np.zeros(0, int), np.zeros(0)))
            continue
        rows = rows.sort_values("frames_before_hit", ascending=False)
        out.append((-rows["frames_before_hit"].to_numpy(int), rows[value].to_numpy(float)))
    return out
