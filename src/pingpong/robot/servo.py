"""Visual servoing: where and when the ball will cross the strike line, from the positions seen so far.

Per axis, a quadratic in time is fitted to the pre-bounce points and, once at least three are seen, another
to the post-bounce points. Until then the post-bounce path is the pre-bounce fit continued through an
elastic bounce: at the instant the fitted height reaches the table (ball centre at table_z + r) the
vertical velocity is reflected and the fitted accelerations are kept, so x and y run on unchanged. The
elastic bounce overestimates the rebound (real restitution ~0.9, spin and friction ignored); the error
shrinks once post-bounce points replace it (tests/test_robot.py measures it on simulated flights).

The bounce is found as the lowest point seen when later points rise again and it lies within
BOUNCE_BAND of the table; that sample (on either side of the true contact) joins neither fit.
The servo runs from 10 frames after the hit, every 10 frames (episode.py).
"""

import numpy as np

from pingpong.frames import BALL_RADIUS, STRIKE_Y

BOUNCE_BAND = 0.05  # m above the resting height within which the lowest seen point counts as the bounce
MIN_FIT_POINTS = 3


def _quadratic(times: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Per-axis least-squares quadratic: coefficients (3, 3), rows [c0, c1, c2] of c0 + c1 t + c2 t^2."""
    vander = np.vander(times, 3, increasing=True)
    return np.linalg.lstsq(vander, positions, rcond=None)[0]


def _first_crossing(c0: float, c1: float, c2: float, level: float, after: float) -> float:
    """Smallest t > after with c0 + c1 t + c2 t^2 = level, or nan."""
    roots = np.roots([c2, c1, c0 - level]) if abs(c2) > 1e-12 else np.array([(level - c0) / c1])
    roots = roots[np.isreal(roots)].real
    roots = roots[roots > after]
    return float(roots.min()) if len(roots) else np.nan


def split_at_bounce(positions: np.ndarray, table_z: float = 0.0) -> tuple[int, int]:
    """(end of pre-bounce, start of post-bounce) indices into the points; (K, K) when no bounce is seen."""
    z = positions[:, 2]
    low = int(np.argmin(z))
    if 0 < low < len(z) - 1 and z[low] < table_z + BALL_RADIUS + BOUNCE_BAND:
        return low, low + 1
    return len(z), len(z)


def servo_strike_estimate(times, ball_positions_seen, strike_y: float = STRIKE_Y, table_z: float = 0.0,
                          ball_radius: float = BALL_RADIUS) -> tuple[np.ndarray, float]:
    """Predicted strike point (x, z) (2,) in m and the time (s, same clock as `times`) the ball crosses y.

    times (K,), ball_positions_seen (K, 3): the ball centres seen so far, ball moving towards -y. Returns
    (nan, nan) and nan when the points cannot give an estimate (fewer than three pre-bounce points, or no
    crossing ahead in the fitted path).
    """
    times = np.asarray(times, float)
    seen = np.asarray(ball_positions_seen, float)
    nan = (np.full(2, np.nan), np.nan)
    pre_end, post_start = split_at_bounce(seen, table_z)
    if len(seen) - post_start >= MIN_FIT_POINTS:
        post = _quadratic(times[post_start:], seen[post_start:])
        t = _first_crossing(*post[:, 1], strike_y, times[pre_end - 1])
        if np.isnan(t):
            return nan
        powers = np.array([1.0, t, t * t])
        return np.array([powers @ post[:, 0], powers @ post[:, 2]]), t
    if pre_end < MIN_FIT_POINTS:
        return nan
    pre = _quadratic(times[:pre_end], seen[:pre_end])
    t_cross = _first_crossing(*pre[:, 1], strike_y, times[0])
    t_bounce = _first_crossing(*pre[:, 2], table_z + ball_radius, times[0])
    if np.isnan(t_cross):
        return nan
    x = pre[0, 0] + pre[1, 0] * t_cross + pre[2, 0] * t_cross**2
    if np.isnan(t_bounce) or t_bounce >= t_cross:  # no bounce before the strike line
        z = pre[0, 2] + pre[1, 2] * t_cross + pre[2, 2] * t_cross**2
        return np.array([x, z]), t_cross
    vz_bounce = pre[1, 2] + 2 * pre[2, 2] * t_bounce
    tau = t_cross - t_bounce
    z = table_z + ball_radius - vz_bounce * tau + pre[2, 2] * tau**2
    return np.array([x, z]), t_cross
