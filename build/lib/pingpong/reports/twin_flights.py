"""The twin's ball flights beside the real MPI ball-gun flights (issue: twin vs real table)."""

import numpy as np
import pandas as pd

from pingpong.frames import FRAME_NS
from pingpong.twin.realdata import flight_stats


def twin_flight_stats(ball: pd.DataFrame, shots: pd.DataFrame) -> list[dict]:
    """flight_stats of every good shot's flight (hit to the receiver), sampled at the camera rate."""
    stats = []
    for shot in shots[shots["outcome"] == "ok"].itertuples():
        rows = ball[(ball["rally"] == shot.rally) & (ball["shot"] == shot.shot)]
        t_ns = rows["time_ns"].to_numpy()
        keep = np.searchsorted(t_ns, np.arange(t_ns[0], t_ns[-1], FRAME_NS))  # 100 Hz, like the cameras
        rows = rows.iloc[np.unique(keep)]
        times = (rows["time_ns"].to_numpy() - t_ns[0]) / 1e9
        try:
            stats.append(flight_stats(times, rows[["x", "y", "z"]].to_numpy(),
                                      rows[["vx", "vy", "vz"]].to_numpy()))
        except ValueError:  # too few samples either side of the bounce to fit
            continue
    return stats

