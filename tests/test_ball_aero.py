"""The twin's lift model: C_L(S) saturating in the spin parameter (pingpong.twin.ball's docstring).

Against the cited data: Stepanek's tennis-ball wind-tunnel fit C_L = 1 / (2 + 1/S) (Am. J. Phys. 56,
138 (1988)) sets the form and the ceiling; the linear Magnus model with the twin's C_M = 0.6 is the
low-spin limit; Miyazaki et al. ("Lift crisis of a spinning table tennis ball", Eur. J. Phys. 38,
024001 (2017)) saw positive lift on 40 mm balls over 0 < S < 1. Then what the saturation does to
real high-spin shots: the old linear lift put a 12 m/s, 80 rev/s loop into the net.
"""

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq

from pingpong.frames import GRAVITY, TABLE_HALF_LENGTH
from pingpong.twin.ball import (
    BallParams,
    _accel,
    aim_shot,
    aim_shots,
    rk4_step,
    sample_ball_params,
    simulate_flight,
)

P = BallParams()
LINEAR = replace(P, max_lift_coefficient=math.inf)  # the twin's former lift, C_L = C_M S
REV = 2 * np.pi  # rad/s per rev/s


def stepanek(s):
    """Stepanek (1988): C_L of spinning tennis balls in a wind tunnel."""
    return 1 / (2 + 1 / np.asarray(s, float))


def vec(lo, hi):
    return st.tuples(*[st.floats(lo, hi, allow_nan=False)] * 3).map(np.array)


def lift_accel(v, w, params=P):
    """The aerodynamic acceleration without gravity and drag: the lift alone."""
    a = np.array(_accel(*v, *w, 0.0, params.k_magnus, params.magnus_saturation))
    return a - [0.0, 0.0, -GRAVITY]


# ---------------------------------------------------------------- the curve against the data

@pytest.mark.parametrize("s", [0.3, 0.5, 1.0, 2.0, 3.0])
def test_lift_within_30_percent_below_stepanek(s):
    # a smooth table-tennis ball: less lift than a felt tennis ball, the same saturation
    assert 0.70 * stepanek(s) <= P.lift_coefficient(s) <= stepanek(s)


def test_ceiling_is_stepaneks():
    assert P.lift_coefficient(1e9) == pytest.approx(0.5, rel=1e-6)
    assert stepanek(1e9) == pytest.approx(0.5, rel=1e-6)


def test_low_spin_limit_is_the_linear_model():
    s = np.array([1e-5, 1e-4, 1e-3])
    ratio = P.lift_coefficient(s) / (P.magnus_coefficient * s)
    np.testing.assert_allclose(ratio, 1 / (1 + P.magnus_coefficient * s / P.max_lift_coefficient))
    assert ratio[0] > 1 - 2e-5
    assert LINEAR.magnus_saturation == 0.0  # C_L_max = inf is exactly the old k_M (w x v)
    v, w = np.array([0.3, -5.0, 1.0]), np.array([40.0, -10.0, 5.0])
    np.testing.assert_allclose(lift_accel(v, w, LINEAR), LINEAR.k_magnus * np.cross(w, v), rtol=1e-12)


def test_low_spin_ball_gun_flight_is_unchanged():
    # 5 m/s with 2 rev/s (S ~ 0.05): the saturation moves the bounce by 1.2 mm
    p0, v0, w0 = [0.0, 1.3, 0.4], [0.0, -4.5, 1.0], [2 * REV, 0.0, 0.0]
    new, old = simulate_flight(p0, v0, w0, P), simulate_flight(p0, v0, w0, LINEAR)
    assert np.linalg.norm(new.events[0].position - old.events[0].position) < 2e-3


def test_lift_is_positive_over_the_measured_range():
    # Miyazaki et al. (2017) found no negative Magnus force for 0 < S < 1 (their valley near S = 0.5
    # is not modelled: the curve is monotone)
    assert np.all(P.lift_coefficient(np.linspace(0.01, 1.0, 100)) > 0)


def test_old_linear_lift_was_about_twice_the_new_at_loop_spins():
    s = 0.02 * 80 * REV / 12.0  # 80 rev/s at 12 m/s
    assert LINEAR.lift_coefficient(s) / P.lift_coefficient(s) == pytest.approx(2.0, abs=0.1)


def test_monotone_concave_and_bounded():
    s = np.concatenate([[0.0], np.geomspace(1e-4, 1e3, 400)])
    c = P.lift_coefficient(s)
    assert c[0] == 0.0 and np.all(np.diff(c) > 0) and np.all(c < P.max_lift_coefficient)
    slope = np.diff(c) / np.diff(s)
    assert np.all(np.diff(slope) < 0) and slope[0] <= P.magnus_coefficient


# ---------------------------------------------------------------- the force in the flight

@settings(max_examples=200, deadline=None)
@given(v=vec(-20, 20), w=vec(-900, 900))
def test_lift_is_across_v_and_matches_c_l(v, w):
    speed = np.linalg.norm(v)
    across = np.linalg.norm(np.cross(w, v))
    if speed < 0.1 or across < 1e-6:
        return
    a = lift_accel(v, w)
    assert abs(a @ v) <= 1e-9 * np.linalg.norm(a) * speed  # no work: lift is across v
    s = P.radius * across / speed**2
    coefficient = np.linalg.norm(a) / (P.air_density * np.pi * P.radius**2 * speed**2 / (2 * P.mass))
    assert coefficient == pytest.approx(float(P.lift_coefficient(s)), rel=1e-9)


@pytest.mark.parametrize("k", [-40.0, 3.0, 150.0])
def test_no_lift_when_spin_is_along_v(k):
    v = np.array([0.4, -6.0, 1.2])
    np.testing.assert_allclose(lift_accel(v, k * v), 0.0, atol=1e-12)
    # a 1 ms step of a ball spinning about its path: lift only as gravity turns v (by 1.6 mrad)
    _, v1 = rk4_step((0.0, 0.0, 1.0), tuple(v), tuple(k * v), 0.0, P.k_magnus, P.magnus_saturation, 1e-3)
    np.testing.assert_allclose(v1, v + [0.0, 0.0, -GRAVITY * 1e-3], atol=3e-5)


def test_ball_at_rest_has_no_lift():
    np.testing.assert_array_equal(lift_accel([0.0, 0.0, 0.0], [300.0, 0.0, 0.0]), 0.0)


@settings(max_examples=25, deadline=None)
@given(v0=vec(-15, 15), w0=vec(-900, 900))
def test_high_spin_flight_never_gains_mechanical_energy(v0, w0):
    flight = simulate_flight([0.0, 0.0, 8.0], v0, w0, P, t_max=0.5)
    energy = 0.5 * np.sum(flight.velocities**2, 1) + GRAVITY * flight.positions[:, 2]
    assert np.all(np.diff(energy) <= 1e-9)


def test_sample_ball_params_varies_the_ceiling():
    many = [sample_ball_params(np.random.default_rng(s), 0.1) for s in range(300)]
    ceilings = np.array([p.max_lift_coefficient for p in many])
    assert np.mean(ceilings) == pytest.approx(P.max_lift_coefficient, rel=0.03)
    assert np.std(ceilings) == pytest.approx(0.1 * P.max_lift_coefficient, rel=0.2)
    assert ceilings.min() > 0


def test_aiming_a_100_rev_s_topspin_shot_lands_on_target():
    # the batched RK4 of aim_shots flies the same saturating lift as simulate_flight
    p_hit, target, w0 = [0.2, 1.8, 0.25], [-0.3, -0.9], [100 * REV, 0.0, 30.0]
    v0 = aim_shot(p_hit, target, w0, P, speed_hint=12.0)
    first = simulate_flight(p_hit, v0, w0, P).events[0]
    assert first.kind == "bounce" and np.linalg.norm(first.position[:2] - target) < 0.01


# ---------------------------------------------------------------- high-spin shots, old against new

def aim_at_speed(params, p_hit, target, w0, speed):
    """The launch velocity (3,) of the fastest flight at `speed` m/s that bounces at target."""
    def excess(flight_time):
        v0, _ = aim_shots(p_hit, target, w0, params, flight_time=flight_time, net_margin=-1.0)
        return np.linalg.norm(v0[0]) - speed
    grid = np.linspace(0.1, 1.2, 45)  # the speed falls with the flight time, then rises again (lobs)
    k = next(i for i in range(len(grid) - 1) if excess(grid[i + 1]) < 0)
    t = brentq(excess, grid[k], grid[k + 1], xtol=1e-9)
    return aim_shots(p_hit, target, w0, params, flight_time=t, net_margin=-1.0)[0][0]


LOOP = (np.array([0.0, TABLE_HALF_LENGTH + 0.3, 0.3]), np.array([0.0, -2 / 3 * TABLE_HALF_LENGTH]),
        np.array([80 * REV, 0.0, 0.0]), 12.0)  # from behind the end line to 2/3 of the far half


def test_topspin_loop_lands_where_the_old_lift_put_it_in_the_net():
    p_hit, target, w0, speed = LOOP
    v0 = aim_at_speed(P, p_hit, target, w0, speed)
    assert 4 < math.degrees(math.atan2(v0[2], -v0[1])) < 9  # a flat, fast loop: measured 6.0 deg
    new = simulate_flight(p_hit, v0, w0, P)
    assert new.events[0].kind == "bounce"
    np.testing.assert_allclose(new.events[0].position[:2], target, atol=0.01)
    old = simulate_flight(p_hit, v0, w0, LINEAR)
    assert old.events[0].kind == "net"  # twice the dip: measured 0.146 m (centre) at the net


def test_loop_aimed_with_the_old_lift_now_flies_long():
    p_hit, target, w0, speed = LOOP
    v0 = aim_at_speed(LINEAR, p_hit, target, w0, speed)  # the old model needs 12.6 deg
    flight = simulate_flight(p_hit, v0, w0, P)
    assert flight.events[0].kind == "floor" and flight.events[0].position[1] < -TABLE_HALF_LENGTH


def test_backspin_push_carried_long_by_the_old_lift():
    p_hit, target, w0 = np.array([0.0, 1.1, 0.2]), np.array([0.0, -0.9]), np.array([-30 * REV, 0.0, 0.0])
    v0 = aim_at_speed(P, p_hit, target, w0, 5.0)
    new, old = simulate_flight(p_hit, v0, w0, P), simulate_flight(p_hit, v0, w0, LINEAR)
    assert new.events[0].kind == old.events[0].kind == "bounce"
    np.testing.assert_allclose(new.events[0].position[:2], target, atol=0.01)
    assert old.events[0].position[1] < target[1] - 0.15  # measured 23 cm long
