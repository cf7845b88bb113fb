"""Visual servoing: where and when the ball will cross the strike line, from the positions seen so far.

Input: the ball centres seen since the opponent's hit (t = 0 at the hit, 100 Hz frames, ball moving
towards -y). Output: a ServoEstimate, the strike point (x, z) at y = strike_y and its time, with a
status from STATUSES: an estimate that cannot be made says why instead of returning a silent nan.

Two fits, by name in SERVO_FITS:

- "paper" (the paper's method, kept as its baseline): per axis a quadratic in time fitted to the
  pre-bounce points and, once at least three are seen, another to the post-bounce points. Until then
  the post-bounce path is the pre-bounce fit continued through an elastic bounce: where the fitted
  height comes down to the table (ball centre at table_z + r) the vertical velocity is reflected and
  the fitted accelerations are kept. The elastic bounce overestimates the rebound (restitution ~0.9,
  spin and friction ignored): strike heights come out ~7 cm high. The bounce is where the fitted
  height comes down through the table height after the last pre-bounce point (BOUNCE_SLACK before
  it at most); a rising crossing, as of a ball hit from below the table's height, is none. On
  drag-slowed flights the y-quadratic can turn back before the strike line: status "no_crossing".
- "model" (the default, DEFAULT_SERVO_FIT): a ball model of the twin's form (pingpong.twin.ball: drag,
  saturating Magnus, Nakashima table bounce with restitution and friction) with its own coefficients
  (`params`; the rules pass the servo's ball of servo_ball.py, fitted on real flights, so the servo never
  shares the twin's coefficients; MODEL_BALL, the twin's nominal, is the default) fitted by Gauss-Newton
  to the points of the current flight segment (pre-bounce, or post-bounce once three are seen), then flown
  forward with simulate_flight, bounce included, to the strike line. The unknowns are the state at the
  segment's last point: position, velocity, spin and the ball's drag relative to the model's. The
  Magnus force shows the spin across v; the part along v only shows as v turns, so a prior holds it:
  before the bounce, little spin about the horizontal direction of travel (strokes give topspin,
  backspin and sidespin); after it, the spin the model bounce gives the pre-bounce fit, which also
  steadies the few post-bounce points, whose curvature alone is mostly noise. A fitted path that
  clips the net flies on: the fit's error there is as large as a ball's clearance.

The bounce among the seen points is the lowest point, over the table, when later points rise again
and it lies within BOUNCE_BAND of the ball's resting height (split_at_bounce); that sample (on either
side of the true contact) joins neither segment. The servo runs from 10 frames after the hit, every 10
frames (episode.py); one estimate costs ~0.1 ms (paper) and ~0.6 ms (model; ~0.75 ms once the bounce
is seen) on one core. tests/test_servo.py and reports/servo_accuracy.py measure both fits.
"""

import math
from collections.abc import Callable
from dataclasses import replace
from typing import NamedTuple

import numpy as np

from pingpong.frames import BALL_RADIUS, GRAVITY, STRIKE_Y, TABLE_HALF_LENGTH, TABLE_HALF_WIDTH
from pingpong.twin.ball import BallParams, rk4_step, simulate_flight, stop_at_y

OK = "ok"
TOO_FEW_POINTS = "too_few_points"  # fewer than MIN_FIT_POINTS usable points in the segment to fit
NO_CROSSING = "no_crossing"  # the fitted path does not reach the strike line (turns back, floor, ...)
STATUSES = (OK, TOO_FEW_POINTS, NO_CROSSING)

BOUNCE_BAND = 0.05  # m above the resting height within which the lowest seen point counts as the bounce
MIN_FIT_POINTS = 3
BOUNCE_SLACK = 0.01  # s: a fitted descent to the table up to a frame before the last point still bounces

MODEL_BALL = BallParams()  # the twin's nominal ball
POSITION_NOISE = 0.002  # m, std of a seen ball centre: weighs the points against the priors
SPIN_PRIOR = 600.0  # rad/s, std of each spin component before any is seen (~100 rev/s)
TRAVEL_SPIN_PRIOR = 100.0  # rad/s, std of the spin about the horizontal direction of travel
BOUNCE_SPIN_PRIOR = 50.0  # rad/s, std of each component of the spin the model bounce predicts
DRAG_PRIOR = 0.05  # relative std of a ball's drag against the model's (the twin varies C_D by 5 %)
FIT_ITERATIONS = 2  # Gauss-Newton steps from the quadratic start: the second changes < 1 mm
MAX_STEP = 0.1  # s, RK4 step back through the seen points (error < 0.1 mm with the Hermite)
FLY_DT = 0.02  # s, simulate_flight step to the strike line (error < 1 mm against 0.5 ms)
MIN_APPROACH_SPEED = 0.1  # m/s towards the strike line: a slower ball is not coming
MAX_FLIGHT = 2.0  # s ahead of the last point: a later crossing is none
MIN_LIFT_FACTOR = 0.2  # floor of C_L / (C_M S) in the start spin: S <= 4 C_L_max / C_M (~3.3)


class ServoEstimate(NamedTuple):
    strike_xz: np.ndarray  # (2,) m where the ball centre crosses y = strike_y; nan unless status is "ok"
    time_s: float  # s, same clock as the input times; nan unless status is "ok"
    status: str  # one of STATUSES

    @property
    def ok(self) -> bool:
        return self.status == OK


def _no_estimate(status: str) -> ServoEstimate:
    return ServoEstimate(np.full(2, np.nan), np.nan, status)


def _valid_points(times, seen) -> tuple[np.ndarray, np.ndarray]:
    """times (K,), seen (K, 3) as float arrays in time order, without the frames that have a nan (no
    ball seen) or repeat a time."""
    times, seen = np.asarray(times, float).ravel(), np.asarray(seen, float).reshape(-1, 3)
    if len(times) != len(seen):
        raise ValueError(f"{len(times)} times for {len(seen)} ball positions")
    keep = np.isfinite(times) & np.isfinite(seen).all(axis=1)
    times, first = np.unique(times[keep], return_index=True)
    return times, seen[keep][first]


def split_at_bounce(positions: np.ndarray, table_z: float = 0.0,
                    ball_radius: float = BALL_RADIUS) -> tuple[int, int]:
    """(end of pre-bounce, start of post-bounce) indices into the points; (K, K) when no bounce is seen.

    The bounce is the lowest point when points follow it, it is over the table and within BOUNCE_BAND
    of the resting height. A ball hit from below the table's height rises from its first point.
    """
    positions = np.asarray(positions, float).reshape(-1, 3)
    if len(positions) < 3:
        return len(positions), len(positions)
    low = int(np.argmin(positions[:, 2]))
    x, y, z = positions[low]
    over_table = abs(x) <= TABLE_HALF_WIDTH + ball_radius and abs(y) <= TABLE_HALF_LENGTH + ball_radius
    if 0 < low < len(positions) - 1 and over_table and z < table_z + ball_radius + BOUNCE_BAND:
        return low, low + 1
    return len(positions), len(positions)


# ---------------------------------------------------------------- the paper's fit

def _quadratic(times: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Per-axis least-squares quadratic: coefficients (3, 3), rows [c0, c1, c2] of c0 + c1 t + c2 t^2."""
    vander = np.vander(times, 3, increasing=True)
    return np.linalg.lstsq(vander, positions, rcond=None)[0]


def _descending_crossing(c0: float, c1: float, c2: float, level: float, after: float) -> float:
    """Smallest t > after where c0 + c1 t + c2 t^2 comes down through level, or nan.

    Both the strike line (y falls) and the bounce (z falls) are descending crossings; a rising one, such
    as a ball hit from below the table's height, is neither.
    """
    roots = np.roots([c2, c1, c0 - level]) if abs(c2) > 1e-12 else np.roots([c1, c0 - level])
    roots = roots[np.isreal(roots)].real
    roots = roots[(roots > after) & (c1 + 2 * c2 * roots < 0)]
    return float(roots.min()) if len(roots) else np.nan


def _at(coefficients: np.ndarray, t: float) -> np.ndarray:
    """Per-axis value (3,) of the quadratics (3, 3) at t."""
    return np.array([1.0, t, t * t]) @ coefficients


def _paper_post_bounce(times, points, strike_y: float, after: float) -> ServoEstimate:
    post = _quadratic(times, points)
    t = _descending_crossing(*post[:, 1], strike_y, after)
    if np.isnan(t):
        return _no_estimate(NO_CROSSING)
    return ServoEstimate(_at(post, t)[[0, 2]], float(t), OK)


def _paper_pre_bounce(times, points, strike_y: float, rest_z: float) -> ServoEstimate:
    """The pre-bounce quadratic to the strike line, through an elastic bounce if it comes down first."""
    pre = _quadratic(times, points)
    t_cross = _descending_crossing(*pre[:, 1], strike_y, times[0])
    if np.isnan(t_cross):
        return _no_estimate(NO_CROSSING)
    x, _, z = _at(pre, t_cross)
    t_bounce = _descending_crossing(*pre[:, 2], rest_z, times[-1] - BOUNCE_SLACK)
    if not np.isnan(t_bounce) and t_bounce < t_cross:
        vz_bounce = pre[1, 2] + 2 * pre[2, 2] * t_bounce
        tau = t_cross - t_bounce
        z = rest_z - vz_bounce * tau + pre[2, 2] * tau**2
    return ServoEstimate(np.array([x, z]), t_cross, OK)


def paper_strike_estimate(times, seen, strike_y: float = STRIKE_Y, table_z: float = 0.0,
                          ball_radius: float = BALL_RADIUS) -> ServoEstimate:
    """The paper's two-quadratic fit with an elastic bounce (module docstring).

    times (K,) s, seen (K, 3) m: the ball centres seen so far; frames with a nan are left out.
    """
    times, seen = _valid_points(times, seen)
    pre_end, post_start = split_at_bounce(seen, table_z, ball_radius)
    if len(seen) - post_start >= MIN_FIT_POINTS:
        return _paper_post_bounce(times[post_start:], seen[post_start:], strike_y, times[pre_end - 1])
    if pre_end < MIN_FIT_POINTS:
        return _no_estimate(TOO_FEW_POINTS)
    return _paper_pre_bounce(times[:pre_end], seen[:pre_end], strike_y, table_z + ball_radius)


# ---------------------------------------------------------------- the model fit

class BallState(NamedTuple):
    time: float  # s
    position: np.ndarray  # (3,) m, ball centre with the table surface at z = 0
    velocity: np.ndarray  # (3,) m/s
    spin: np.ndarray  # (3,) rad/s
    drag_scale: float  # this ball's drag over the model's


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b of two 3-vectors (np.cross costs ~10x more on a single pair)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _cross_matrix(a: np.ndarray) -> np.ndarray:
    """[a]x, the matrix with [a]x b = a x b."""
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def _travel_direction(velocity: np.ndarray) -> np.ndarray:
    """Unit horizontal direction of travel, or zeros for a steep flight that has none to go by."""
    horizontal = np.array([velocity[0], velocity[1], 0.0])
    norm = np.linalg.norm(horizontal)
    return horizontal / norm if norm > 0.3 * np.linalg.norm(velocity) else np.zeros(3)


def _start_spin(start: np.ndarray, params: BallParams) -> np.ndarray:
    """The spin from the quadratic's acceleration: across v (v x (w x v) = w |v|^2 for w across v), with
    the part along v (no effect on the acceleration) that leaves no spin about the direction of travel.

    The lift is k_M f (w x v) with f = 1 / (1 + s_M |w x v| / |v|^2), so f = 1 - s_M |lift| / (k_M |v|^2);
    f is floored at MIN_LIFT_FACTOR where the noisy curvature asks for more lift than C_L_max gives.
    """
    v = start[1]
    magnus = 2 * start[2] - [0.0, 0.0, -GRAVITY] + params.k_drag * np.linalg.norm(v) * v
    gain = params.k_magnus - params.magnus_saturation * np.linalg.norm(magnus) / (v @ v)  # k_M f
    spin = _cross(v, magnus) / (max(gain, MIN_LIFT_FACTOR * params.k_magnus) * (v @ v))
    travel = _travel_direction(v)
    along = v / np.linalg.norm(v)
    return spin - (spin @ travel) / (along @ travel) * along if travel.any() else spin


def _positions_back(state: BallState, taus: np.ndarray, params: BallParams) -> np.ndarray:
    """Model positions (n, 3) at times state.time + taus (taus <= 0, ascending, taus[0] < 0).

    RK4 backwards in equal steps of at most MAX_STEP, cubic Hermite on (p, v) between the steps
    (error ~ h^4 |d4p/dt4| / 384 ~ 1e-6 m): the step count does not grow with the number of points.
    """
    n = max(math.ceil(-taus[0] / MAX_STEP - 1e-9), 1)
    h = taus[0] / n
    kd, km, ks = params.k_drag * state.drag_scale, params.k_magnus, params.magnus_saturation
    p, v, w = tuple(state.position.tolist()), tuple(state.velocity.tolist()), tuple(state.spin.tolist())
    knots_p, knots_v = [p], [v]
    for _ in range(n):
        p, v = rk4_step(p, v, w, kd, km, ks, h)
        knots_p.append(p), knots_v.append(v)
    knots_p, knots_v = np.array(knots_p), np.array(knots_v)
    u = taus / h
    i = np.minimum(u.astype(int), n - 1)
    s = (u - i)[:, None]
    return ((2 * s**3 - 3 * s**2 + 1) * knots_p[i] + (s**3 - 2 * s**2 + s) * h * knots_v[i]
            + (3 * s**2 - 2 * s**3) * knots_p[i + 1] + (s**3 - s**2) * h * knots_v[i + 1])


def _lift(velocity: np.ndarray, spin: np.ndarray, params: BallParams):
    """The ball model's lift acceleration k_M f c (c = w x v, f = 1 / (1 + s_M |c| / |v|^2)), its
    derivative by c, L = k_M f (I - (1 - f) c c^T / |c|^2), and by v through |v|^2 (both (3, 3))."""
    c, speed2 = _cross(spin, velocity), velocity @ velocity
    size = np.linalg.norm(c)
    f = 1 / (1 + params.magnus_saturation * size / speed2)
    lift = params.k_magnus * f * c
    along = np.outer(c, c) / size**2 if size > 0 else np.zeros((3, 3))
    by_cross = params.k_magnus * f * (np.eye(3) - (1 - f) * along)
    return lift, by_cross, 2 * (1 - f) / speed2 * np.outer(lift, velocity)


def _design(taus: np.ndarray, state: BallState, params: BallParams) -> np.ndarray:
    """d positions / d unknowns (3n, 10) to third order in tau: position, velocity, spin, drag scale.

    With a = g - s k_D |v| v + lift(w x v, |v|) (_lift: L its derivative by w x v) and J = da/dv, a
    change dv0 moves p(tau) by (tau + tau^2/2 J + tau^3/6 J^2) dv0; dw by
    (tau^2/2 M + tau^3/6 (J M - L [a]x)) dw, M = -L [v]x, with L held at the state's (it changes
    slowly); the third order keeps Gauss-Newton converging in one or two steps on 0.3 s of flight.
    """
    v = state.velocity
    speed = np.linalg.norm(v)
    lift, by_cross, by_speed = _lift(v, state.spin, params)
    drag_unit = -params.k_drag * speed * v  # d a / d s
    accel = np.array([0.0, 0.0, -GRAVITY]) + state.drag_scale * drag_unit + lift
    jac = -params.k_drag * state.drag_scale * (speed * np.eye(3) + np.outer(v, v) / speed)
    jac += by_cross @ _cross_matrix(state.spin) + by_speed
    by_spin = -by_cross @ _cross_matrix(v)
    drag_rate = -params.k_drag * (speed * accel + (v @ accel) / speed * v)  # d/dt of d a / d s
    coefficients = np.zeros((4, 3, 10))  # of tau^k / k!
    coefficients[0, :, :3] = np.eye(3)
    coefficients[1, :, 3:6] = np.eye(3)
    coefficients[2, :, 3:] = np.hstack([jac, by_spin, drag_unit[:, None]])
    coefficients[3, :, 3:] = np.hstack([jac @ jac, jac @ by_spin - by_cross @ _cross_matrix(accel),
                                        (jac @ drag_unit + drag_rate)[:, None]])
    powers = taus[:, None] ** np.arange(4) / [1.0, 1.0, 2.0, 6.0]
    return (powers @ coefficients.reshape(4, 30)).reshape(-1, 10)


def _spin_prior(velocity: np.ndarray, bounce_spin: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Spin prior (mean (3,), information matrix (3, 3) in 1/(rad/s)^2), see _fit_flight."""
    if bounce_spin is not None:
        return bounce_spin, np.eye(3) / BOUNCE_SPIN_PRIOR**2
    travel = _travel_direction(velocity)
    return np.zeros(3), np.eye(3) / SPIN_PRIOR**2 + np.outer(travel, travel) / TRAVEL_SPIN_PRIOR**2


def _fit_flight(times, points, params: BallParams, bounce_spin: np.ndarray | None = None,
                drag_prior: float = 1.0, iterations: int = FIT_ITERATIONS) -> BallState | None:
    """The model state at the last point that fits the points best (Gauss-Newton, module docstring), or
    None when the points do not come towards the strike line at MIN_APPROACH_SPEED at least.

    Gaussian priors: the drag scale drag_prior with std DRAG_PRIOR; the spin, before the bounce, zero
    with std SPIN_PRIOR and TRAVEL_SPIN_PRIOR about the direction of travel (strokes give topspin,
    backspin and sidespin); after it (bounce_spin given: the spin the model bounce predicts)
    bounce_spin with std BOUNCE_SPIN_PRIOR.
    """
    taus = times - times[-1]
    start = _quadratic(taus, points)
    if not start[1, 1] < -MIN_APPROACH_SPEED:
        return None
    spin = _start_spin(start, params) if bounce_spin is None else bounce_spin
    state = BallState(float(times[-1]), start[0], start[1], spin, drag_prior)
    spin_mean, spin_information = _spin_prior(start[1], bounce_spin)
    variance = POSITION_NOISE**2  # the priors' information in units of the points'
    for _ in range(iterations):
        design = _design(taus, state, params)
        residual = (points - _positions_back(state, taus, params)).ravel()
        normal, gradient = design.T @ design, design.T @ residual
        normal[6:9, 6:9] += variance * spin_information
        gradient[6:9] += variance * spin_information @ (spin_mean - state.spin)
        normal[9, 9] += variance / DRAG_PRIOR**2
        gradient[9] += variance / DRAG_PRIOR**2 * (drag_prior - state.drag_scale)
        step = np.linalg.solve(normal, gradient)
        state = BallState(state.time, state.position + step[:3], state.velocity + step[3:6],
                          state.spin + step[6:9], float(np.clip(state.drag_scale + step[9], 0.5, 2.0)))
    return state


def _fly_to_strike_line(state: BallState | None, strike_y: float, table_z: float,
                        params: BallParams) -> ServoEstimate:
    """The model flight from state to the strike line, bounce included; no crossing for no state (the
    points did not approach)."""
    if state is None or not state.velocity[1] < -MIN_APPROACH_SPEED:
        return _no_estimate(NO_CROSSING)
    params = replace(params, drag_coefficient=params.drag_coefficient * state.drag_scale)
    flight = simulate_flight(state.position, state.velocity, state.spin, params, dt=FLY_DT,
                             t_max=MAX_FLIGHT, stop=stop_at_y(strike_y))
    t_start = state.time
    if flight.events and flight.events[-1].kind == "net":
        # the fit's error near the net is a few cm, as is a ball's clearance: fly on through the net
        t_start += flight.times[-1]
        past_net = flight.positions[-1] * [1.0, 0.0, 1.0] - [0.0, 1e-9, 0.0]
        flight = simulate_flight(past_net, flight.velocities[-1], flight.spins[-1], params, dt=FLY_DT,
                                 t_max=MAX_FLIGHT, stop=stop_at_y(strike_y))
    if not flight.events or flight.events[-1].kind != "stop":
        return _no_estimate(NO_CROSSING)
    x, _, z = flight.positions[-1]
    return ServoEstimate(np.array([x, z + table_z]), float(t_start + flight.times[-1]), OK)


def _spin_after_bounce(state: BallState, t_after: float, params: BallParams) -> np.ndarray:
    """The spin of the model flight from state at t_after (s), a time after the seen bounce."""
    params = replace(params, drag_coefficient=params.drag_coefficient * state.drag_scale)
    flight = simulate_flight(state.position, state.velocity, state.spin, params, dt=FLY_DT,
                             t_max=t_after - state.time + BOUNCE_SLACK)
    return flight.spins[-1]


def _seen_crossing(times, seen, strike_y: float) -> ServoEstimate | None:
    """The crossing interpolated between seen points once a point is at or past the strike line."""
    past = np.flatnonzero(seen[:, 1] <= strike_y)
    if len(past) == 0:
        return None
    i = past[0]
    if i == 0:
        return _no_estimate(NO_CROSSING)  # the first point is already past: not an incoming ball
    f = (seen[i - 1, 1] - strike_y) / (seen[i - 1, 1] - seen[i, 1])
    point = seen[i - 1] + f * (seen[i] - seen[i - 1])
    return ServoEstimate(point[[0, 2]], float(times[i - 1] + f * (times[i] - times[i - 1])), OK)


def model_strike_estimate(times, seen, strike_y: float = STRIKE_Y, table_z: float = 0.0,
                          ball_radius: float = BALL_RADIUS, params: BallParams = MODEL_BALL) -> ServoEstimate:
    """The ball model fitted to the current segment and flown to the strike line (module docstring).

    times (K,) s, seen (K, 3) m: the ball centres seen so far; frames with a nan are left out.
    params: the ball model (its radius is replaced by ball_radius).
    """
    times, seen = _valid_points(times, seen)
    if len(seen) < MIN_FIT_POINTS:
        return _no_estimate(TOO_FEW_POINTS)
    if (crossed := _seen_crossing(times, seen, strike_y)) is not None:
        return crossed
    params = replace(params, radius=ball_radius)
    points = seen - [0.0, 0.0, table_z]  # the model's table surface is z = 0
    pre_end, post_start = split_at_bounce(seen, table_z, ball_radius)
    if len(seen) - post_start < MIN_FIT_POINTS:  # fly the pre-bounce fit through the model bounce
        if pre_end < MIN_FIT_POINTS:
            return _no_estimate(TOO_FEW_POINTS)
        pre = _fit_flight(times[:pre_end], points[:pre_end], params)
        return _fly_to_strike_line(pre, strike_y, table_z, params)
    bounce_spin, drag_prior = None, 1.0
    pre = None  # one Gauss-Newton step is enough for the post-bounce fit's priors
    if pre_end >= MIN_FIT_POINTS:
        pre = _fit_flight(times[:pre_end], points[:pre_end], params, iterations=1)
    if pre is not None:  # the same ball: its drag, and the spin the model bounce leaves it with
        bounce_spin, drag_prior = _spin_after_bounce(pre, times[post_start], params), pre.drag_scale
    post = _fit_flight(times[post_start:], points[post_start:], params, bounce_spin, drag_prior)
    return _fly_to_strike_line(post, strike_y, table_z, params)


SERVO_FITS: dict[str, Callable[..., ServoEstimate]] = {
    "paper": paper_strike_estimate,
    "model": model_strike_estimate,
}
DEFAULT_SERVO_FIT = "model"
