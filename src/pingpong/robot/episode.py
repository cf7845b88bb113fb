"""One simulated strike: the robot follows goals on the strike line while one post-hit ball flies in.

Clock: t = 0 at the opponent's hit, camera frames every 10 ms (frames.CAMERA_FPS); the controller steps
at ControlParams.dt. Goals, each usable `latency_frames` after it was computed:
  - anticipation: the strike point predicted at pre-hit frames (optional input), one every
    `anticipation_period_frames`; the robot may move on them from `anticipation_start_frame` with speed
    share alpha1 before the hit and alpha2 after it, until the first servo goal is usable;
  - visual servoing: a servo fit (servo.SERVO_FITS, `servo_fit`) of the ball positions seen at frames
    0..f, for f = servo_start_frame, + servo_period_frames, ..., moved on with speed share alpha_servo.
    A fit that gives no estimate is a stated state: the robot keeps its last goal, and the episode
    counts those updates (servo_no_estimate). The servo sees the ball through the regime's sensing
    (regimes.Sensing: noise, dropped frames, a delay of `delay_frames`: at frame f it fits frames up to
    f - delay_frames).
Two timings are named (config robot.regimes, paper and fine):
  - paper (the defaults here): the paper's appendix. Goals change once every 10 frames (10 Hz), the
    joints integrate theta <- theta + 0.1 s theta_dot (0.1 s control steps, which is how the paper models
    its 100 ms latency: a goal computed at t drives the robot over [t, t + 0.1 s]; no delay on top), the
    predictions of t = -10 and t = 0 are the anticipation goals (alpha1 acts on the first over
    [-0.1, 0) s, alpha2 on the second over [0, 0.1) s), and the first servo goal is computed at t = +10
    and used at once.
  - fine: 10 ms steps with the 100 ms latency added on top of them, anticipation goals every frame (the
    prediction of t = -20 is the first, usable at t = -10), the first servo goal usable at t = +20.
Visual servoing alone is alpha1 = alpha2 = 0 (the robot waits at home until the first servo goal);
the basic anticipatory controller is alpha1 = alpha2 = 1. `alpha` may instead be given per step (an
array over episode_times, or a function of t) so a confidence-scaled policy plugs in.

Hit: when the ball centre crosses the strike line (linear interpolation of the ball track), the paddle
centre is within hit_radius (the 8 cm paddle radius) of it, in 3D; the paddle there is the forward
kinematics of the joints at that instant (within a step they move at the step's constant velocity, so
this is exact for any step length). Contacts on the rim (up to radius + ball radius) count as misses:
the ball must land on the face. Limits are checked at every step (velocity, acceleration between
steps, position) and reported.
"""

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import NamedTuple

import numpy as np

from pingpong.frames import CAMERA_FPS
from pingpong.robot.control import ControlParams, control_step
from pingpong.robot.model import PADDLE_RADIUS, Robot, paddle_position
from pingpong.robot.regimes import Sensing, sense
from pingpong.robot.servo import SERVO_FITS
from pingpong.twin.ball import BallParams

FRAME_DT = 1.0 / CAMERA_FPS
LIMIT_TOLERANCE = 1e-9  # relative, for the recorded limit checks (floating-point rounding only)


@dataclass(frozen=True)
class EpisodeParams:
    alpha1: float = 0.0  # speed share on the prediction before the hit
    alpha2: float = 0.0  # speed share on the prediction after the hit, until the first servo goal
    alpha_servo: float = 1.0  # speed share on the servo's goals
    # the paper's timing (module docstring); config robot.regimes names it and the fine one
    anticipation_start_frame: int = -10  # the first step (frames from the hit) that may move on a prediction
    anticipation_period_frames: int = 10  # frames between the anticipation goals used
    servo_start_frame: int = 10
    servo_period_frames: int = 10
    latency_frames: int = 0  # frames between computing a goal and moving on it
    servo_fit: str = "model"  # servo.SERVO_FITS
    servo_ball: BallParams | None = None  # the model fit's ball (None: servo.MODEL_BALL)
    sensing: Sensing = field(default_factory=Sensing)  # the ball as the servo sees it
    hit_radius: float = PADDLE_RADIUS  # m
    control: ControlParams = field(default_factory=lambda: ControlParams(dt=0.1))


def anticipation_frames(frames: np.ndarray, params: EpisodeParams) -> np.ndarray:
    """Mask of the prediction frames (F,) whose goals the robot uses: every anticipation_period_frames-th,
    counted from the one first usable at the anticipation start."""
    first = params.anticipation_start_frame - params.latency_frames
    frames = np.asarray(frames, int)
    return (frames >= first) & ((frames - first) % params.anticipation_period_frames == 0)


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


class GoalSchedule(NamedTuple):
    times: np.ndarray  # (G,) s from the hit, from which each goal is usable, in time order
    goals: np.ndarray  # (G, 2) strike points (x, z), m
    first_servo: float  # s, when the first servo goal is usable (inf: never)
    servo_no_estimate: int  # servo updates whose fit gave no estimate (the last goal was kept)


def goal_schedule(ball_times: np.ndarray, ball_positions: np.ndarray, t_end: float,
                  predictions: tuple[np.ndarray, np.ndarray] | None, params: EpisodeParams) -> GoalSchedule:
    """The anticipation goals (the used prediction frames, anticipation_frames) and the servo goals.

    ball_times, ball_positions: the ball as the servo sees it; it fits the track at the camera frames
    0..f (interpolated onto them) up to t_end."""
    latency = params.latency_frames * FRAME_DT
    times, goals = [], []
    if predictions is not None:
        frames, strike_xz = np.asarray(predictions[0]), np.asarray(predictions[1], float)
        used = anticipation_frames(frames, params) & np.isfinite(strike_xz).all(axis=1)
        times += list(frames[used] * FRAME_DT + latency)
        goals += list(strike_xz[used])
    first_servo, no_estimate = np.inf, 0
    fit = SERVO_FITS[params.servo_fit]
    if params.servo_fit == "model" and params.servo_ball is not None:
        fit = partial(fit, params=params.servo_ball)
    last_frame = int(np.floor(min(t_end, ball_times[-1]) / FRAME_DT + 1e-9))
    frame_times = FRAME_DT * np.arange(last_frame + 1)
    seen = np.column_stack([np.interp(frame_times, ball_times, ball_positions[:, k]) for k in range(3)])
    seen = sense(frame_times, seen, params.sensing)
    delay = params.sensing.delay_frames
    for f in range(params.servo_start_frame, last_frame + 1, params.servo_period_frames):
        estimate = fit(frame_times[:f + 1 - delay], seen[:f + 1 - delay], params.control.strike_y)
        if estimate.status != "ok":
            no_estimate += 1
            continue
        times.append(f * FRAME_DT + latency), goals.append(estimate.strike_xz)
        first_servo = min(first_servo, f * FRAME_DT + latency)
    order = np.argsort(times, kind="stable")
    return GoalSchedule(np.asarray(times, float)[order], np.asarray(goals, float).reshape(-1, 2)[order],
                        first_servo, no_estimate)


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
                q0: np.ndarray | None = None, seen: tuple[np.ndarray, np.ndarray] | None = None,
                schedule: GoalSchedule | None = None) -> dict:
    """Simulate the robot over one post-hit flight and say whether it hits the ball.

    ball_times (N,) s from the hit, ball_positions (N, 3): the ball's track (e.g. twin.ball.simulate_flight
    with stop_at_y(STRIKE_Y)). predictions: (pre-hit frame numbers (F,), predicted strike points (F, 2)),
    e.g. frames -30..-1. alpha overrides the alpha1/alpha2/alpha_servo schedule: an array over
    episode_times(...) or a function of t. q0: start configuration at rest (default: home). seen:
    (times, positions) of the ball as the servo sees it (flights.HitFlight; default: the track itself).
    schedule: goal_schedule's result for these arguments, when the caller has it (the servo fits are the
    episode's costliest part; evaluate.simulate_hit needs them for its alphas too).
    Returns hit, end_distance_m, strike_time_s, ball_strike (3,), paddle_strike (3,), the limit checks
    (limits_ok, max_velocity_ratio, max_acceleration_ratio, min_position_margin), servo_no_estimate
    (GoalSchedule) and the trajectory
    (times, q, qd, paddle, goal, alpha).
    """
    ball_times = np.asarray(ball_times, float)
    ball_positions = np.asarray(ball_positions, float)
    control = params.control
    t_strike, ball_strike = strike_crossing(ball_times, ball_positions, control.strike_y)
    t_end = t_strike if np.isfinite(t_strike) else ball_times[-1]
    times = episode_times(t_end, params)
    if schedule is None:
        seen_times, seen_positions = (ball_times, ball_positions) if seen is None else map(np.asarray, seen)
        schedule = goal_schedule(seen_times, seen_positions, t_end, predictions, params)
    goal_times, goals = schedule.times, schedule.goals
    if alpha is None:
        alphas = alpha_schedule(times, schedule.first_servo, params)
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
        paddle_strike = paddle_position(robot, q[k] + f * (q[min(k + 1, n - 1)] - q[k]))
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
        "servo_no_estimate": schedule.servo_no_estimate,
        "times": times, "q": q, "qd": qd, "paddle": paddle,
        "goal": np.where(goal_index[:, None] >= 0, goals[np.maximum(goal_index, 0)] if len(goals) else np.nan,
                         np.nan),
        "alpha": alphas,
    }
