"""The simulated robot: kinematics against an independent DH chain, the control law's limits and
convergence, the servo's strike estimate on simulated flights, torque-derived accelerations, episodes."""

from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from workflow_util import ROBOT_LIMITS, ROBOT_URDF

from pingpong.frames import GRAVITY, STRIKE_Y
from pingpong.robot.control import ControlParams, braking_speed, control_step
from pingpong.robot.episode import EpisodeParams, run_episode
from pingpong.robot.model import (
    N_BASE,
    load_robot,
    paddle_jacobian,
    paddle_position,
    random_configurations,
    read_limits,
    worst_case_accelerations,
)
from pingpong.robot.servo import paper_strike_estimate, split_at_bounce
from pingpong.twin.ball import aim_shots, simulate_flight, stop_at_y

ROBOT = load_robot(ROBOT_URDF, ROBOT_LIMITS)
LIMIT_TOL = 1e-9  # relative: floating-point rounding only

# Standard DH table of the LBR iiwa 14 R820 (written from KUKA's link lengths, not from the URDF):
# T_i = Rz(q_i) Tz(d_i) Rx(alpha_i), a_i = 0.
DH_D = np.array([0.36, 0.0, 0.42, 0.0, 0.40, 0.0, 0.126])
DH_ALPHA = np.array([-1, 1, 1, -1, -1, 1, 0]) * np.pi / 2
# The arm base in the table frame for base joints (bx, by): the base square's centre at (0, -2.77) on the
# floor (z = -0.76), the arm 0.25 m forward of the base centre and 0.45 m above the floor.
MOUNT = np.array([0.0, -2.77 + 0.25, -0.76 + 0.45])
PADDLE_OFFSET = 0.02  # disc centre beyond the flange, along the flange axis


def dh_flange(q: np.ndarray) -> np.ndarray:
    """4x4 flange pose in the table frame by the DH chain."""
    pose = np.eye(4)
    pose[:3, 3] = MOUNT + [q[0], q[1], 0.0]
    for theta, d, alpha in zip(q[N_BASE:], DH_D, DH_ALPHA, strict=True):
        ct, st_, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
        pose = pose @ np.array([[ct, -st_ * ca, st_ * sa, 0], [st_, ct * ca, -ct * sa, 0],
                                [0, sa, ca, d], [0, 0, 0, 1]])
    return pose


def unit_q(values) -> np.ndarray:
    return ROBOT.q_min + np.asarray(values) * (ROBOT.q_max - ROBOT.q_min)


configurations = st.lists(st.floats(0.0, 1.0), min_size=9, max_size=9)


# ---------------------------------------------------------------- model

@settings(max_examples=200, deadline=None)
@given(configurations)
def test_flange_and_paddle_match_dh_chain(values):
    q = unit_q(values)
    flange = dh_flange(q)
    pin.framesForwardKinematics(ROBOT.model, ROBOT.data, q)
    assert np.allclose(ROBOT.data.oMf[ROBOT.flange_frame].translation, flange[:3, 3], atol=1e-6)
    paddle, rotation, _ = paddle_jacobian(ROBOT, q)
    assert np.allclose(paddle, flange[:3, 3] + PADDLE_OFFSET * flange[:3, 2], atol=1e-6)
    assert np.allclose(rotation[:, 2], flange[:3, 2], atol=1e-9)  # the disc normal is the flange axis


@settings(max_examples=30, deadline=None)
@given(configurations, st.lists(st.floats(-1.0, 1.0), min_size=9, max_size=9))
def test_jacobian_is_local_world_aligned(values, direction):
    """Rows 0-2: d(paddle centre)/dq in the table frame; rows 3-5: the angular velocity in the table frame."""
    q, dq = unit_q(values), np.asarray(direction)
    _, rot0, jac = paddle_jacobian(ROBOT, q)
    p0 = paddle_jacobian(ROBOT, q)[0].copy()
    h = 1e-6
    p1, rot1, _ = paddle_jacobian(ROBOT, q + h * dq)
    assert np.allclose((p1 - p0) / h, jac[:3] @ dq, atol=1e-5)
    omega = pin.log3(rot1 @ rot0.T) / h
    assert np.allclose(omega, jac[3:] @ dq, atol=1e-5)


def test_urdf_limits_equal_the_published_ones_and_limits_yaml():
    limits = read_limits(ROBOT_LIMITS)
    deg = np.deg2rad
    assert np.allclose(ROBOT.q_max[N_BASE:], deg([170, 120, 170, 120, 170, 120, 175]))
    assert np.allclose(ROBOT.v_max[N_BASE:], deg([85, 85, 100, 75, 130, 135, 135]))
    assert np.allclose(ROBOT.tau_max, [320, 320, 176, 176, 110, 40, 40])
    assert np.allclose(ROBOT.v_max[:N_BASE], 1.1) and np.allclose(ROBOT.a_max[:N_BASE], 15.0)
    assert np.allclose(ROBOT.q_max[:N_BASE] - ROBOT.q_min[:N_BASE], 2.0)  # the 2 m square
    model = pin.buildModelFromUrdf(str(ROBOT_URDF))
    assert np.allclose(model.lowerPositionLimit, limits["q_min"])
    assert np.allclose(model.upperPositionLimit, limits["q_max"])
    assert np.allclose(model.velocityLimit, limits["v_max"])
    assert np.allclose(model.effortLimit[N_BASE:], limits["tau_max"])


def test_arm_mass_near_datasheet():
    # links 1-7 and the paddle hang on the arm joints; + Drake's 5 kg link 0 - the 0.2 kg paddle = the arm
    carried = sum(ROBOT.model.inertias[j].mass for j in range(1 + N_BASE, ROBOT.model.njoints))
    assert abs(carried + 5.0 - 0.2 - 29.9) < 1.0  # KUKA's ~29.9 kg


def test_home_faces_the_opponent_on_the_strike_line():
    p, rot, _ = paddle_jacobian(ROBOT, ROBOT.q_home)
    assert np.allclose(p, [0.0, STRIKE_Y, 0.30], atol=1e-4)
    assert np.allclose(rot[:, 2], [0, 1, 0], atol=1e-4)


def test_worst_case_accelerations_positive_plausible_and_above_the_limits_used():
    acc = worst_case_accelerations(ROBOT, np.random.default_rng(0), n_samples=300)
    for key in ("simple_min", "coupled_min"):
        assert np.all(acc[key] > 0)
    assert np.all(acc["coupled_min"] <= acc["simple_min"] + 1e-9)
    # shoulder and elbow joints carry the arm: tens to hundreds of rad/s^2
    assert np.all((acc["coupled_min"][:4] > 10) & (acc["coupled_min"][:4] < 1000))
    # Drake's accelerations can be produced within the torque limits everywhere
    assert np.all(read_limits(ROBOT_LIMITS, "drake")["a_max"][N_BASE:] < acc["coupled_min"])


def test_the_default_accelerations_are_the_papers_table_6():
    table6_deg = [3.69e3, 3.47e3, 7.42e3, 1.37e4, 3.79e4, 3.81e5, 5.72e5]  # deg/s^2, A1..A7
    np.testing.assert_allclose(np.rad2deg(ROBOT.a_max[N_BASE:]), table6_deg, rtol=1e-5)
    drake = read_limits(ROBOT_LIMITS, "drake")["a_max"]
    np.testing.assert_allclose(drake[N_BASE:], [8.57, 8.57, 8.74, 11.36, 12.23, 15.72, 15.72])
    assert np.allclose(drake[:N_BASE], 15.0)
    with pytest.raises(ValueError, match="acceleration set 'nope'"):
        read_limits(ROBOT_LIMITS, "nope")


# ---------------------------------------------------------------- control

@settings(max_examples=200, deadline=None)
@given(st.floats(0.0, 2.0), st.floats(0.1, 20.0), st.sampled_from([1e-3, 1e-2]))
def test_braking_speed_stops_before_the_limit(distance, a_max, dt):
    v = float(braking_speed(np.array(distance), np.array(a_max), dt))
    travelled = 0.0
    while v > 0:
        travelled += v * dt
        v -= a_max * dt
    assert travelled <= distance + 1e-12


def run_to(goal_sequence, q0, alpha=1.0, params: ControlParams | None = None, steps_per_goal=10, robot=ROBOT):
    """Run the controller over goals switched every steps_per_goal steps; returns states and paddle path."""
    params = params or ControlParams()
    q, qd = q0.copy(), np.zeros(9)
    qs, qds, paddles = [q], [qd], []
    for goal in goal_sequence:
        for _ in range(steps_per_goal):
            q, qd, p = control_step(robot, q, qd, goal, alpha, params)
            qs.append(q), qds.append(qd), paddles.append(p)
    return np.array(qs), np.array(qds), np.array(paddles)


def assert_within_limits(qs, qds, dt):
    assert np.all(np.abs(qds) <= ROBOT.v_max * (1 + LIMIT_TOL))
    assert np.all(np.abs(np.diff(qds, axis=0)) <= ROBOT.a_max * dt * (1 + LIMIT_TOL))
    assert np.all((qs >= ROBOT.q_min) & (qs <= ROBOT.q_max))


def test_limits_never_exceeded_over_random_goals_and_starts():
    rng = np.random.default_rng(7)
    starts = [ROBOT.q_home] + list(random_configurations(ROBOT, rng, 5))
    for q0 in starts:
        goals = np.column_stack([rng.uniform(-2.0, 2.0, 15), rng.uniform(-0.8, 1.5, 15)])  # some unreachable
        qs, qds, _ = run_to(goals, q0, alpha=rng.uniform(0.2, 1.0))
        assert_within_limits(qs, qds, ControlParams().dt)


def test_limits_hold_at_1khz():
    rng = np.random.default_rng(8)
    params = ControlParams(dt=1e-3)
    goals = np.column_stack([rng.uniform(-1.0, 1.0, 6), rng.uniform(0.0, 0.8, 6)])
    qs, qds, _ = run_to(goals, ROBOT.q_home, params=params, steps_per_goal=100)
    assert_within_limits(qs, qds, params.dt)


@pytest.mark.parametrize("accelerations, tolerance_m", [("drake", 0.01), ("table6", 0.04)])
def test_100hz_and_1khz_paths_agree(accelerations, tolerance_m):
    """The 10 ms law against 1 kHz: within 1 cm where the accelerations bind (Drake's); with Table 6's the
    discrete feedback itself (1 - K dt per step) shapes the path, 3 cm apart at most (measured)."""
    robot = load_robot(ROBOT_URDF, ROBOT_LIMITS, accelerations)
    goals = [np.array([0.5, 0.1]), np.array([-0.6, 0.5])]
    coarse = run_to(goals, robot.q_home, steps_per_goal=50, robot=robot)[2]
    fine = run_to(goals, robot.q_home, params=ControlParams(dt=1e-3), steps_per_goal=500, robot=robot)[2]
    fine = fine[::10]
    assert np.linalg.norm(coarse - fine, axis=1).max() < tolerance_m


@pytest.mark.parametrize("goal", [(0.0, 0.1), (0.5, 0.5), (-0.6, 0.2), (0.7, 0.0), (-0.3, 0.6)])
def test_reachable_goal_is_reached_within_1cm_in_1s(goal):
    _, _, paddles = run_to([np.array(goal)], ROBOT.q_home, steps_per_goal=100)
    target = np.array([goal[0], STRIKE_Y, goal[1]])
    assert np.linalg.norm(paddles[-1] - target) < 0.01
    q_end = run_to([np.array(goal)], ROBOT.q_home, steps_per_goal=101)[0][-1]
    assert paddle_jacobian(ROBOT, q_end)[1][1, 2] > np.cos(np.deg2rad(2))  # facing +y within 2 deg


def test_unreachable_goal_stops_at_the_limit():
    qs, qds, paddles = run_to([np.array([3.0, 0.3])], ROBOT.q_home, steps_per_goal=300)
    assert_within_limits(qs, qds, ControlParams().dt)
    assert qs[-1, 0] == pytest.approx(ROBOT.q_max[0], abs=1e-3)  # the base at the end of its square
    assert np.abs(qds[-50:]).max() < 1e-3  # and at rest
    assert paddles[-1, 0] > 1.1
    qs, qds, _ = run_to([np.array([0.0, 3.0])], ROBOT.q_home, steps_per_goal=300)  # far above: arm stretched
    assert_within_limits(qs, qds, ControlParams().dt)
    assert np.abs(qds[-50:]).max() < 0.05


def test_alpha_scales_the_speed():
    goal = [np.array([0.6, 0.3])]
    _, fast, _ = run_to(goal, ROBOT.q_home, alpha=1.0, steps_per_goal=40)
    _, slow, _ = run_to(goal, ROBOT.q_home, alpha=0.3, steps_per_goal=40)
    _, still, _ = run_to(goal, ROBOT.q_home, alpha=0.0, steps_per_goal=40)
    normalised = lambda qd: np.max(np.abs(qd) / ROBOT.v_max)  # noqa: E731
    assert normalised(fast) == pytest.approx(1.0, abs=1e-6)
    assert normalised(slow) <= 0.3 + 1e-6
    assert normalised(still) == 0.0


# ---------------------------------------------------------------- servo

def test_servo_exact_on_drag_free_parabola_with_elastic_bounce():
    """Without drag and with an elastic bounce, the quadratic fit plus reflection is exact."""
    p0, v0, r = np.array([0.2, 1.6, 0.3]), np.array([-0.3, -6.0, 1.0]), 0.02
    # bounce time: z(t) = r
    t_b = (v0[2] + np.sqrt(v0[2] ** 2 + 2 * GRAVITY * (p0[2] - r))) / GRAVITY
    t_c = (STRIKE_Y - p0[1]) / v0[1]
    assert t_b < t_c
    tau = t_c - t_b
    vz_b = v0[2] - GRAVITY * t_b
    expected = np.array([p0[0] + v0[0] * t_c, r - vz_b * tau - 0.5 * GRAVITY * tau**2])
    times = np.arange(0, 0.15, 0.01)
    seen = p0 + v0 * times[:, None] + np.outer(times**2, [0, 0, -0.5 * GRAVITY])
    estimate = paper_strike_estimate(times, seen)
    xz, t = estimate.strike_xz, estimate.time_s
    assert np.allclose(xz, expected, atol=1e-9) and t == pytest.approx(t_c, abs=1e-9)


def simulated_flights(n: int, rng: np.random.Generator):
    p_hit = np.column_stack([rng.uniform(-0.5, 0.5, n), rng.uniform(1.5, 1.9, n), rng.uniform(0.1, 0.4, n)])
    target = np.column_stack([rng.uniform(-0.6, 0.6, n), rng.uniform(-1.2, -0.4, n)])
    spin = np.column_stack([rng.uniform(-150, 150, n), rng.uniform(-30, 30, n), rng.uniform(-50, 50, n)])
    v0, _ = aim_shots(p_hit, target, spin, speed_hint=9.0)
    flights = [simulate_flight(p_hit[i], v0[i], spin[i], stop=stop_at_y(STRIKE_Y)) for i in range(n)]
    assert all(f.events[-1].kind == "stop" for f in flights)  # every ball reaches the strike line
    return flights


FLIGHTS = simulated_flights(16, np.random.default_rng(3))


def test_servo_error_falls_as_more_of_the_flight_is_seen():
    """Tolerances (drag, Magnus, Nakashima bounce in the flights): before three post-bounce points are seen
    (elastic-bounce extrapolation) within 25 cm; after, within 4 cm; time of crossing within 15 ms then."""
    first, last = [], []
    for flight in FLIGHTS:
        t_c, crossing = flight.times[-1], flight.positions[-1]
        frames = np.arange(0, int(t_c / 0.01) + 1) * 0.01
        seen = np.column_stack([np.interp(frames, flight.times, flight.positions[:, k]) for k in range(3)])
        errors = []
        for k in range(10, len(frames), 10):
            estimate = paper_strike_estimate(frames[:k + 1], seen[:k + 1])
            xz, t = estimate.strike_xz, estimate.time_s
            error = np.linalg.norm(xz - crossing[[0, 2]])
            post_points = k + 1 - split_at_bounce(seen[:k + 1])[1]
            assert error < (0.04 if post_points >= 3 else 0.25)
            if post_points >= 3:
                assert abs(t - t_c) < 0.015
            errors.append(error)
        first.append(errors[0]), last.append(errors[-1])
    assert np.median(last) < 0.25 * np.median(first)


# ---------------------------------------------------------------- episodes

FINE = EpisodeParams(anticipation_period_frames=1, latency_frames=10, control=ControlParams(dt=0.01))


@pytest.mark.parametrize("timing, servo_moves_at, anticipation_moves_at", [
    # the paper's: 0.1 s steps, the servo goal computed at frame 10 drives the step from 0.1 s (the
    # velocity it sets is recorded at the step's end, 0.2 s); anticipation from the step at -0.1 s
    (EpisodeParams(), 0.2, 0.0),
    # the fine one: frame 10 + 10 frames latency = 0.2 s, recorded at 0.21 s; anticipation from -0.1 s
    (FINE, 0.21, -0.09)])
def test_episode_visual_servoing_waits_and_anticipation_moves_early(timing, servo_moves_at,
                                                                     anticipation_moves_at):
    flight = FLIGHTS[0]
    crossing = flight.positions[-1]
    predictions = (np.arange(-30, 1), np.tile(crossing[[0, 2]], (31, 1)))
    servo = run_episode(ROBOT, flight.times, flight.positions, predictions, timing)
    anticipate = run_episode(ROBOT, flight.times, flight.positions, predictions,
                             replace(timing, alpha1=1.0, alpha2=1.0))
    for out in (servo, anticipate):
        assert out["limits_ok"]
        assert out["hit"] == (out["end_distance_m"] <= 0.08)
        assert out["strike_time_s"] == pytest.approx(flight.times[-1], abs=1e-6)  # event located to ~1e-6
    moving = np.abs(servo["qd"]).max(axis=1) > 0  # first nonzero velocity
    assert servo["times"][np.argmax(moving)] == pytest.approx(servo_moves_at, abs=1e-9)
    moving = np.abs(anticipate["qd"]).max(axis=1) > 0
    assert anticipate["times"][np.argmax(moving)] == pytest.approx(anticipation_moves_at, abs=1e-9)


def test_the_paddle_at_the_strike_is_the_kinematics_between_steps():
    """With 0.1 s steps the strike falls inside a step: the joints move at the step's constant velocity,
    so the paddle there is the forward kinematics of the interpolated joints, not a blend of positions."""
    flight = FLIGHTS[2]
    predictions = (np.arange(-30, 1), np.tile(flight.positions[-1, [0, 2]], (31, 1)))
    out = run_episode(ROBOT, flight.times, flight.positions, predictions, EpisodeParams(alpha1=1, alpha2=1))
    k = np.searchsorted(out["times"], out["strike_time_s"]) - 1
    f = (out["strike_time_s"] - out["times"][k]) / 0.1
    q = out["q"][k] + f * (out["q"][k + 1] - out["q"][k])
    np.testing.assert_allclose(out["paddle_strike"], paddle_position(ROBOT, q), atol=1e-12)


def test_anticipation_on_perfect_predictions_beats_servoing_alone():
    hits = {"servo": [], "anticipate": []}
    for flight in FLIGHTS[:10]:
        predictions = (np.arange(-30, 1), np.tile(flight.positions[-1, [0, 2]], (31, 1)))
        for name, params in (("servo", EpisodeParams()), ("anticipate", EpisodeParams(alpha1=1, alpha2=1))):
            out = run_episode(ROBOT, flight.times, flight.positions, predictions, params)
            assert out["limits_ok"]
            hits[name].append(out["end_distance_m"])
    assert np.mean(hits["anticipate"]) < np.mean(hits["servo"])


def test_per_step_alpha_plugs_in():
    flight = FLIGHTS[1]
    predictions = (np.arange(-30, 1), np.tile(flight.positions[-1, [0, 2]], (31, 1)))
    scheduled = run_episode(ROBOT, flight.times, flight.positions, predictions, replace(FINE, alpha1=0.5,
                                                                                        alpha2=0.5))
    as_array = run_episode(ROBOT, flight.times, flight.positions, predictions, FINE, alpha=scheduled["alpha"])
    as_function = run_episode(ROBOT, flight.times, flight.positions, predictions, FINE,
                              alpha=lambda t: 0.0 if t < -0.1 - 1e-12 else (0.5 if t < 0.2 - 1e-12 else 1.0))
    assert np.array_equal(as_array["q"], scheduled["q"])
    assert np.allclose(as_function["q"], scheduled["q"])
    with pytest.raises(ValueError, match="one value per step"):
        run_episode(ROBOT, flight.times, flight.positions, predictions, alpha=np.ones(3))
