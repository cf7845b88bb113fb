"""One simulated strike: the robot follows goals on the strike line while one post-hit ball flies in.

Clock: t = 0 at the opponent's hit, camera frames every 10 ms (frames.CAMERA_FPS); the controller steps
at ControlParams.dt (one frame by default). Goals, each usable `latency_frames` after it was computed:
  - anticipation: the strike point predicted at each pre-hit frame (optional input); the robot may move
    on it from `anticipation_start_frame` (-10: 0.1 s before the hit) with speed share alpha1 before the
    hit and alpha2 after it, until the first servo goal is usable;
  - visual servoing: servo_strike_estimate on the ball positions seen at frames 0..f, for f = 10, 20, ...
    (from 10 frames after the hit, every 10 frames), moved on with speed share alpha_servo.
Visual servoing alone is alpha1 = alpha2 = 0 (the robot waits at home until the first servo goal, at
0.2 s); the basic anticipatory controller is alpha1 = alpha2 = 1. `alpha` may instead be given per step
(an array over episode_times, or a function of t) so a confidence-scaled policy plugs in.

Hit: when the ball centre crosses the strike line (linear interpolation of the ball track), the paddle
centre (interpolated between control steps) is within hit_radius (the 8 cm paddle radius) of it, in 3D.
Contacts on the rim (up to radius + ball radius) count as misses: the ball must land on the face.
Limits are checked at every step (velocity, acceleration between steps, position) and reported.
"""

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from pingpong.frames import CAMERA_FPS
from pingpong.robot.control import ControlParams, control_step
from pingpong.robot.model import PADDLE_RADIUS, Robot, paddle_position
from pingpong.robot.servo import servo_strike_estimate

FRAME_DT = 1.0 / CAMERA_FPS
LIMIT_TOLERANCE = 1e-9  # relative, for the recorded limit checks (floating-point rounding only)


@dataclass(frozen=True)
class EpisodeParams:
    alpha1: float = 0.0  # speed share on the prediction before the hit
    alpha2: float = 0.0  # speed share on the prediction after the hit, until the first servo goal
    alpha_servo: float = 1.0  # speed share on the servo's goals
    anticipation_start_frame: int = -10
    servo_start_frame: int = 10
    servo_period_frames: int = 10
    latency_frames: int = 10  # 100 ms between seeing and moving on it
    hit_radius: float = PADDLE_RADIUS  # m
    control: ControlParams = field(default_factory=ControlParams)


def strike_crossing(times: np.ndarray, positions: np.ndarray, strike_y: float) -> tuple[float, np.ndarray]:
    """Time and ball centre (3,) where the track first reaches y = strike_y going towards -y; nan if never."""
    y = positions[:, 1] - strike_y
    crossed = np.flatnonzero((y[:-1] > 0) & (y[1:] <= 0))
    if len(crossed) == 0:
        return np.nan, np.full(3, np.nan)
    i = crossed[0]
    f = y[i] / (y[i] - y[i + 1])
    return (float(times[i] + f * (times[i + 1] - times[i])),
            positions[i] + f * (positions[i + 1] - positions[i]))


def episode_times(t_end: float, params: EpisodeParams = EpisodeParams()) -> np.ndarray:
    """Control-step times from the anticipation start (or the hit, if later) to the first step >= t_end."""
    dt = params.control.dt
    t0 = min(params.anticipation_start_frame, 0) * FRAME_DT
    return t0 + dt * np.arange(int(np.ceil((t_end - t0) / dt - 1e-9)) + 1)


def goal_schedule(ball_times: np.ndarray, ball_positions: np.ndarray, t_end: float,
                  predictions: tuple[np.ndarray, np.ndarray] | None,
                  params: EpisodeParams) -> tuple[np.ndarray, np.ndarray, float]:
    """Goals as (usable-from times (G,), strike points (G, 2)) in time order, and the first servo time."""
    latency = params.latency_frames * FRAME_DT
    times, goals = [], []
    if predictions is not None:
        frames, strike_xz = np.asarray(predictions[0]), np.asarray(predictions[1], float)
        for f, xz in zip(frames, strike_xz, strict=True):
            if np.all(np.isfinite(xz)):
                times.append(f * FRAME_DT + latency), goals.append(xz)
    first_servo = np.inf
    last_frame = int(np.floor(min(t_end, ball_times[-1]) / FRAME_DT + 1e-9))
    frame_times = FRAME_DT * np.arange(last_frame + 1)
    seen = np.column_stack([np.interp(frame_times, ball_times, ball_positions[:, k]) for k in range(3)])
    for f in range(params.servo_start_frame, last_frame + 1, params.servo_period_frames):
        xz, _ = servo_strike_estimate(frame_times[:f + 1], seen[:f + 1], params.control.strike_y)
        if np.all(np.isfinite(xz)):
            times.append(f * FRAME_DT + latency), goals.append(xz)
            first_servo = min(first_servo, f * FRAME_DT + latency)
    order = np.argsort(times, kind="stable")
    return np.asarray(times)[order], np.asarray(goals).reshape(-1, 2)[order], first_servo


def alpha_schedule(times: np.ndarray, first_servo: float, params: EpisodeParams) -> np.ndarray:
    """Per-step speed share: 0 before the anticipation start, alpha1 before the hit, alpha2 until the first
    servo goal is usable, alpha_servo after."""
    start = params.anticipation_start_frame * FRAME_DT
    return np.select([times < start - 1e-12, times < -1e-12, times < first_servo - 1e-12],
                     [0.0, params.alpha1, params.alpha2], params.alpha_servo)


def run_episode(robot: Robot, ball_times, ball_positions,
                predictions: tuple[np.ndarray, np.ndarray] | None = None,
                params: EpisodeParams = EpisodeParams(),
                alpha: np.ndarray | Callable[[float], float] | None = None,
                q0: np.ndarray | None = None) -> dict:
    """Simulate the robot over one post-hit flight and say whether it hits the ball.

    ball_times (N,) s from the hit, ball_positions (N, 3): the ball's track (e.g. twin.ball.simulate_flight
    with stop_at_y(STRIKE_Y)). predictions: (pre-hit frame numbers (F,), predicted strike points (F, 2)),
    e.g. frames -30..-1. alpha overrides the alpha1/alpha2/alpha_servo schedule: an array over
    episode_times(...) or a function of t. q0: start configuration at rest (default: home).
    Returns hit, end_distance_m, strike_time_s, ball_strike (3,), paddle_strike (3,), the limit checks
    (limits_ok, max_velocity_ratio, max_acceleration_ratio, min_position_margin) and the trajectory
    (times, q, qd, paddle, goal, alpha).
    """
    ball_times = np.asarray(ball_times, float)
    ball_positions = np.asarray(ball_positions, float)
    control = params.control
    t_strike, ball_strike = strike_crossing(ball_times, ball_positions, control.strike_y)
    t_end = t_strike if np.isfinite(t_strike) else ball_times[-1]
    times = episode_times(t_end, params)
    goal_times, goals, first_servo = goal_schedule(ball_times, ball_positions, t_end, predictions, params)
    if alpha is None:
        alphas = alpha_schedule(times, first_servo, params)
    elif callable(alpha):
        alphas = np.array([alpha(t) for t in times], float)
    else:
        alphas = np.asarray(alpha, float)
        if alphas.shape != times.shape:
            raise ValueError(f"alpha has shape {alphas.shape}, expected one value per step {times.shape}")
    goal_index = np.searchsorted(goal_times, times + 1e-12, side="right") - 1

    n = len(times)
    q = np.empty((n, robot.model.nq))
    qd = np.zeros((n, robot.model.nv))
    paddle = np.empty((n, 3))
    q[0] = robot.q_home if q0 is None else q0
    rest_paddle = None
    for k in range(n - 1):
        idle = goal_index[k] < 0 or alphas[k] <= 0
        if idle and not qd[k].any():  # at rest with nothing to do: skip the kinematics
            if rest_paddle is None or not np.array_equal(q[k], q[k - 1]):
                rest_paddle = paddle_position(robot, q[k])
            q[k + 1], paddle[k] = q[k], rest_paddle
            continue
        goal = None if goal_index[k] < 0 else goals[goal_index[k]]
        q[k + 1], qd[k + 1], paddle[k] = control_step(robot, q[k], qd[k], goal, alphas[k], control)
    paddle[-1] = paddle_position(robot, q[-1])

    if np.isfinite(t_strike):
        k = min(np.searchsorted(times, t_strike, side="right") - 1, n - 2) if n > 1 else 0
        f = (t_strike - times[k]) / control.dt if n > 1 else 0.0
        paddle_strike = paddle[k] + f * (paddle[min(k + 1, n - 1)] - paddle[k])
        end_distance = float(np.linalg.norm(paddle_strike - ball_strike))
    else:
        paddle_strike, end_distance = np.full(3, np.nan), np.nan
    velocity_ratio = np.max(np.abs(qd) / robot.v_max)
    acceleration_ratio = np.max(np.abs(np.diff(qd, axis=0)) / control.dt / robot.a_max) if n > 1 else 0.0
    position_margin = np.min(np.minimum(q - robot.q_min, robot.q_max - q))
    return {
        "hit": bool(end_distance <= params.hit_radius),
        "end_distance_m": end_distance,
        "strike_time_s": t_strike,
        "ball_strike": ball_strike,
        "paddle_strike": paddle_strike,
        "limits_ok": bool(velocity_ratio <= 1 + LIMIT_TOLERANCE and acceleration_ratio <= 1 + LIMIT_TOLERANCE
                          and position_margin >= 0),
        "max_velocity_ratio": float(velocity_ratio),
        "max_acceleration_ratio": float(acceleration_ratio),
        "min_position_margin": float(position_margin),
        "times": times, "q": q, "qd": qd, "paddle": paddle,
        "goal": np.where(goal_index[:, None] >= 0, goals[np.maximum(goal_index, 0)] if len(goals) else np.nan,
                         np.nan),
        "alpha": alphas,
    }
