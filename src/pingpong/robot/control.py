"""The paper's control law: resolved-rate control of the paddle towards a goal on the strike line.

Task (5 rows): the paddle centre's position (3) goes to (x_goal, STRIKE_Y, z_goal), and the disc normal n
turns to +y (2 rows: the angular velocity about n does not move a disc's face, so only its components on
the paddle's in-plane axes e1, e2 are tasks). The commanded task velocity is position feedback
    U = K [p_goal - p ; e1.(n x y) ; e2.(n x y)]      (n x y rotates n towards +y)
and the joint direction d = J^+ U with J = the 5 x 9 task Jacobian (base and arm together).

J^+ is the damped (lambda) pseudo-inverse in velocity-limit-normalised coordinates, J^+ = W (J W)^+ with
W = diag(v_max): the least-norm solution of q_dot_i / v_max_i, so metres of base and radians of arm are
traded by how fast each can move. lambda^2 = damping^2 + error_damping |U|^2 grows with the task error,
as in Levenberg-Marquardt IK (Sugihara, "Solvability-unconcerned inverse kinematics by the
Levenberg-Marquardt method", IEEE T-RO 2011): without it an unreachable goal (the arm stretched out)
makes the arm chatter at the workspace boundary; with it the arm comes to rest there, and near the goal
the damping shrinks back to `damping`. The speed along d is set separately (below), so the extra damping
shapes the direction only. A secondary task in the nullspace of J pulls the arm joints towards the home
posture (keeps them away from their limits).

Speed along the commanded direction c = d + d_null (the paper's alpha and beta): q_dot = s c with
    s = min(1, alpha * beta_v, beta_brake),   beta_v = min_i v_max_i / |c_i|,
so alpha is the proportion of the largest speed along c that the velocity limits allow, s = 1 is plain
proportional feedback (reached near the goal), and beta_brake keeps every joint slow enough to stop at
the goal (J^+ e = d / K is the remaining joint displacement) with its acceleration limit. The admissible
joint velocities of this step form per-joint intervals: the velocity limits, the acceleration limits
around the previous velocity (|dq_dot| <= a_max dt), and a braking bound before each position limit
(the velocity from which decelerating at a_max stops in time, exact for this discrete integration). The
scale is the admissible one nearest s along c (so the direction is kept); when no scale fits (c turned
faster than the joints can follow), each joint's velocity is clipped into its interval instead, which
bends the direction but never breaches a limit. Positions are finally clamped to their limits (never
active when the braking bound holds; episode.py checks).

Timing: the controller integrates at dt (semi-implicit Euler: the new velocity, then q += q_dot dt):
0.1 s in the paper's timing (theta <- theta + 0.1 theta_dot; with K = 10 1/s one unconstrained step
reaches the goal), 10 ms in the fine one (episode.py). At 1 kHz the 10 ms law gives the same paddle
paths within 1 cm under Drake's accelerations and within 3 cm under Table 6's (tests/test_robot.py).
"""

from dataclasses import dataclass

import numpy as np

from pingpong.frames import STRIKE_Y
from pingpong.robot.model import N_BASE, Robot, paddle_jacobian


@dataclass(frozen=True)
class ControlParams:
    dt: float = 0.01  # s, integration and control step
    gain: float = 10.0  # 1/s, K of the position and orientation feedback
    damping: float = 0.02  # lambda of the damped pseudo-inverse (normalised units)
    error_damping: float = 0.02  # s^2: lambda^2 += this * |U|^2 (Levenberg-Marquardt, see module docstring)
    nullspace_gain: float = 1.0  # 1/s, pull of the arm joints towards home in the task's nullspace
    strike_y: float = STRIKE_Y  # m, the y of every goal


def braking_denominator(distance: np.ndarray, a_max: np.ndarray, dt: float) -> np.ndarray:
    """sqrt(1/4 + 2 d / (a dt^2)) + 1/2: braking_speed(d) = (2 d / dt) / this (see braking_speed)."""
    return np.sqrt(0.25 + 2.0 * np.maximum(distance, 0.0) / (a_max * dt * dt)) + 0.5


def braking_speed(distance: np.ndarray, a_max: np.ndarray, dt: float) -> np.ndarray:
    """Largest speed towards a limit `distance` away from which braking at a_max stops before it.

    Semi-implicit steps move v dt, (v - a dt) dt, ...: from v = n a dt they cover a dt^2 n (n + 1) / 2, so
    n = sqrt(1/4 + 2 d / (a dt^2)) - 1/2, written as 2 d / (a dt^2) / (sqrt(...) + 1/2) to stay exact for
    small d. For non-integer n the path is up to a dt^2 / 8 longer, which is taken off d first.
    """
    reach = np.maximum(distance - a_max * dt * dt / 8, 0.0)
    return 2.0 * reach / dt / braking_denominator(reach, a_max, dt)


def task(robot: Robot, q: np.ndarray, goal_xz: np.ndarray, params: ControlParams):
    """Task Jacobian (5, 9), task error (5,) [position (3), orientation (2)] and the paddle centre (3,)."""
    p, rot, jac = paddle_jacobian(robot, q)
    task_jac = np.empty((5, jac.shape[1]))
    task_jac[:3] = jac[:3]
    task_jac[3:] = rot[:, :2].T @ jac[3:]  # e1, e2 rows of the angular part
    n = rot[:, 2]
    # e_k . (n x y), with n x y = (-n_z, 0, n_x) written out (np.cross costs more than the rest of task)
    error = np.array([goal_xz[0] - p[0], params.strike_y - p[1], goal_xz[1] - p[2],
                      rot[2, 0] * n[0] - rot[0, 0] * n[2], rot[2, 1] * n[0] - rot[0, 1] * n[2]])
    return task_jac, error, p.copy()


def resolve(task_jac: np.ndarray, task_velocity: np.ndarray, robot: Robot, q: np.ndarray,
            params: ControlParams) -> tuple[np.ndarray, np.ndarray]:
    """Joint directions (9,) of the task (W (JW)^+ U) and of the nullspace pull towards home."""
    w = robot.v_max
    jw = task_jac * w
    pull = params.nullspace_gain * (robot.q_home - q) / w
    pull[:N_BASE] = 0.0
    # (JW)^+ = (JW)^T (JW (JW)^T + lambda^2 I)^-1: one 5 x 5 solve for both right-hand sides
    gram = jw @ jw.T
    gram.flat[:: len(gram) + 1] += params.damping**2 + params.error_damping * (task_velocity @ task_velocity)
    rhs = np.empty((len(gram), 2))  # (column_stack's wrapper costs more than the solve at this size)
    rhs[:, 0], rhs[:, 1] = task_velocity, jw @ pull
    sol = np.linalg.solve(gram, rhs)
    direction = w * (jw.T @ sol[:, 0])
    null = w * (pull - jw.T @ sol[:, 1])
    return direction, null


def velocity_bounds(robot: Robot, q: np.ndarray, qd: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-joint interval of admissible new velocities: velocity, acceleration and braking-to-limit bounds."""
    a_dt = robot.a_max * dt
    to_max, to_min = robot.q_max - q, q - robot.q_min
    # braking only binds within v_max^2 / (2 a_max) + one step of a limit; skip its square roots elsewhere
    free = robot.v_max * (robot.v_max / (2 * robot.a_max) + dt)
    if (to_max > free).all() and (to_min > free).all():
        hi, lo = robot.v_max, -robot.v_max
    else:
        hi = np.minimum(robot.v_max, braking_speed(to_max, robot.a_max, dt))
        lo = -np.minimum(robot.v_max, braking_speed(to_min, robot.a_max, dt))
    # clipping into the acceleration interval: if the velocity interval is out of reach, brake as hard
    # as allowed (the acceleration bound wins)
    acc_lo, acc_hi = qd - a_dt, qd + a_dt
    return np.minimum(np.maximum(lo, acc_lo), acc_hi), np.minimum(np.maximum(hi, acc_lo), acc_hi)


def scale_along(direction: np.ndarray, wanted: float, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """New velocity s * direction with s the admissible scale nearest `wanted`; per-joint clip if none."""
    moving = direction != 0
    if moving.all():
        inv = 1.0 / direction
        a, b = lo * inv, hi * inv
        s_lo, s_hi = np.minimum(a, b).max(), np.maximum(a, b).min()
    elif np.all((lo[~moving] <= 0) & (hi[~moving] >= 0)):  # the joints with d_i = 0 can stay still
        inv = 1.0 / direction[moving]
        a, b = lo[moving] * inv, hi[moving] * inv
        s_lo, s_hi = np.minimum(a, b).max(initial=-np.inf), np.maximum(a, b).min(initial=np.inf)
    else:
        s_lo, s_hi = 1.0, 0.0
    if s_lo <= s_hi:
        return min(max(wanted, s_lo), s_hi) * direction
    return np.minimum(np.maximum(wanted * direction, lo), hi)


def control_step(robot: Robot, q: np.ndarray, qd: np.ndarray, goal_xz: np.ndarray | None, alpha: float,
                 params: ControlParams = ControlParams()) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One step of the control law: (q, qd) -> (q_next, qd_next, paddle centre at q).

    goal_xz None (no goal yet) brakes to rest; alpha in [0, 1] is the speed share along the commanded
    direction (0 also brakes to rest, within the acceleration limits).
    """
    lo, hi = velocity_bounds(robot, q, qd, params.dt)
    if goal_xz is None or alpha <= 0:
        qd_new = np.minimum(np.maximum(0.0, lo), hi)
        q_new = np.minimum(np.maximum(q + qd_new * params.dt, robot.q_min), robot.q_max)
        return q_new, qd_new, paddle_jacobian(robot, q)[0].copy()
    task_jac, error, p = task(robot, q, goal_xz, params)
    direction, null = resolve(task_jac, params.gain * error, robot, q, params)
    commanded = direction + null
    fastest = (np.abs(commanded) / robot.v_max).max()
    beta_v = 1.0 / fastest if fastest > 0 else np.inf
    # each joint's remaining displacement is |d_i| / K; the scale whose speed can still stop there is
    # braking_speed(|d_i| / K) / |d_i|, written without the division so that d_i = 0 is harmless
    gain_dt = params.gain * params.dt
    beta_brake = 2.0 / gain_dt / braking_denominator(np.abs(direction) / params.gain, robot.a_max,
                                                     params.dt).max()
    wanted = min(1.0, alpha * beta_v, beta_brake)
    qd_new = scale_along(commanded, wanted, lo, hi)
    q_new = np.minimum(np.maximum(q + qd_new * params.dt, robot.q_min), robot.q_max)
    return q_new, qd_new, p
