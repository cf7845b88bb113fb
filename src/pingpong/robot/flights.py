"""The measured post-hit flights the simulated robot plays against, and the predictions it anticipates on.

A flight is a 3D ball track from the hit on, in seconds from the hit, mirrored like the dataset's input
for a 'far' hitter (curation.labels.mirror_points) so that every ball travels towards the robot at
y = STRIKE_Y. It is cut one sample past its first crossing of the strike line: later samples (the robot's
side's return) are not the same flight. Each hit has two tracks of one flight:
  - the judged flight: the zero-phase filtered ball (interim/filtered/), the best estimate of where the
    ball went, on which a hit is decided;
  - the seen flight: the ball as the robot's visual servoing sees it, of the inputs' kind (causal: the
    cleaned measurements of interim/causal/, past-only; zero_phase: the judged flight itself).
"""

from typing import NamedTuple

import numpy as np
import pandas as pd

from pingpong.common.artifacts import read_table
from pingpong.curation.causal import causal_lowpass
from pingpong.curation.labels import mirror_points
from pingpong.curation.schemas import HIT_KEYS
from pingpong.frames import STRIKE_Y
from pingpong.perception.schemas import BALL3D


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


def read_ball_tables(sessions: list[str], judged: list, seen: list,
                     seen_cutoff_hz: float | None) -> tuple[dict, dict | None]:
    """(judged, seen) session -> ball table (time_ns, x, y, z) for hit_flights: judged from the filtered
    tables, seen from the causal inputs' cleaned tables low-passed forwards as the model's ball inputs are
    (curation.dataset; seen_cutoff_hz None: unfiltered); seen [] (zero-phase inputs): None."""
    columns = ["time_ns", "x", "y", "z"]
    judged_balls = {s: read_table(f, BALL3D, columns=columns) for s, f in zip(sessions, judged, strict=True)}
    if not seen:
        return judged_balls, None
    seen_balls = {}
    for s, f in zip(sessions, seen, strict=True):
        ball = read_table(f, BALL3D, columns=columns)
        held = causal_lowpass(ball[["x", "y", "z"]].to_numpy(float), [seen_cutoff_hz] * 3)
        # the servo sees a frame only where it was measured (the hold is the filter's state, not a sighting)
        ball[["x", "y", "z"]] = np.where(np.isfinite(ball[["x", "y", "z"]].to_numpy(float)), held, np.nan)
        seen_balls[s] = ball
    return judged_balls, seen_balls


class HitFlight(NamedTuple):
    times: np.ndarray  # (N,) s from the hit: the judged flight
    positions: np.ndarray  # (N, 3) m
    seen_times: np.ndarray  # (M,) s: the flight as the servo sees it
    seen_positions: np.ndarray  # (M, 3) m


def hit_flights(hits: pd.DataFrame, balls: dict[str, pd.DataFrame], max_duration_s: float = 1.5,
                seen_balls: dict[str, pd.DataFrame] | None = None) -> list[HitFlight]:
    """HitFlight of every row of a DATASET table (session, t_hit_ns, hitter), in row order: judged on
    `balls`, seen on `seen_balls` (None: the same tables)."""
    out = []
    for h in hits.itertuples(index=False):
        judged = hit_flight(balls[h.session], int(h.t_hit_ns), h.hitter, max_duration_s)
        seen = judged if seen_balls is None else hit_flight(seen_balls[h.session], int(h.t_hit_ns), h.hitter,
                                                            max_duration_s)
        out.append(HitFlight(*judged, *seen))
    return out


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
