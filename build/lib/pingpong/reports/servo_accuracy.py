"""How well the visual servo's fits (robot.servo.SERVO_FITS) estimate the strike point on measured flights.

For each flight, fit and frame f after the hit, the fit sees the points with time <= f frames and its
strike point is compared with the flight's own crossing of the strike line: the track linearly
interpolated where y first goes from > strike_y to <= strike_y. Flights that never cross are skipped;
so, for a frame, are the flights that have already crossed by then (nothing is left to predict).
The error is the distance in the (x, z) plane at the strike line; a fit without an estimate counts in
no_estimate_share and in its status column, not in the error quantiles.
"""

from collections.abc import Callable, Mapping, Sequence

import numpy as np
import pandas as pd

from pingpong.frames import CAMERA_FPS, STRIKE_Y
from pingpong.robot.servo import SERVO_FITS, STATUSES, ServoEstimate

FRAME_DT = 1.0 / CAMERA_FPS  # s
TIME_TOL = 1e-9  # s: a frame's own sample counts as seen despite float rounding


def strike_crossing(times: np.ndarray, positions: np.ndarray,
                    strike_y: float = STRIKE_Y) -> tuple[np.ndarray, float] | None:
    """(x, z) (2,) m and time (s) where the track first goes from y > strike_y to y <= strike_y, or None."""
    y = positions[:, 1]
    crossing = np.flatnonzero((y[:-1] > strike_y) & (y[1:] <= strike_y))
    if len(crossing) == 0:
        return None
    i = crossing[0]
    f = (y[i] - strike_y) / (y[i] - y[i + 1])
    point = positions[i] + f * (positions[i + 1] - positions[i])
    return point[[0, 2]], float(times[i] + f * (times[i + 1] - times[i]))


def _fit_row(fit: Callable[..., ServoEstimate], tracks, frame: int, strike_y: float) -> dict:
    """One fit at one frame over the tracks (times, positions, crossing xz, crossing time)."""
    t_seen = frame * FRAME_DT + TIME_TOL
    errors, statuses = [], []
    for times, positions, cross_xz, t_cross in tracks:
        if t_cross <= t_seen:
            continue
        seen = times <= t_seen
        estimate = fit(times[seen], positions[seen], strike_y=strike_y)
        statuses.append(estimate.status)
        if estimate.ok:
            errors.append(np.linalg.norm(estimate.strike_xz - cross_xz))
    errors_cm = 100 * np.asarray(errors)
    row = {"frames_after_hit": frame, "n_flights": len(statuses),
           "median_error_cm": float(np.median(errors_cm)) if len(errors) else np.nan,
           "p90_error_cm": float(np.percentile(errors_cm, 90)) if len(errors) else np.nan,
           "no_estimate_share": 1 - len(errors) / len(statuses) if statuses else np.nan}
    return row | {f"n_{status}": statuses.count(status) for status in STATUSES}


def servo_accuracy(flights: Sequence[tuple[np.ndarray, np.ndarray]],
                   fits: Mapping[str, Callable[..., ServoEstimate]] = SERVO_FITS,
                   frames_after_hit: Sequence[int] = (10, 15, 20),
                   strike_y: float = STRIKE_Y) -> pd.DataFrame:
    """One row per fit and frame after the hit: fit, frames_after_hit, n_flights, median_error_cm,
    p90_error_cm, no_estimate_share and n_<status> per status (module docstring).

    flights: (times (N,) s from the hit, positions (N, 3) m) tracks, frames every 10 ms, possibly with
    missing frames.
    """
    tracks = []
    for times, positions in flights:
        times, positions = np.asarray(times, float), np.asarray(positions, float)
        if (crossing := strike_crossing(times, positions, strike_y)) is not None:
            tracks.append((times, positions, *crossing))
    rows = [{"fit": name} | _fit_row(fit, tracks, frame, strike_y)
            for name, fit in fits.items() for frame in frames_after_hit]
    return pd.DataFrame(rows)
