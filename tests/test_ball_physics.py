"""Ball physics: flight against closed forms, the Nakashima bounce, energy, events, paddle, aiming."""

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pingpong.frames import NET_HEIGHT
from pingpong.twin.ball import (
    FLOOR_Z,
    GRAVITY,
    BallParams,
    aim_shot,
    aim_shots,
    bounce,
    paddle_for_outgoing,
    paddle_impact,
    sample_ball_params,
    simulate_flight,
    stop_at_y,
)

P = BallParams()
NO_SPIN = np.zeros(3)


def vec(lo, hi):
    return st.tuples(*[st.floats(lo, hi, allow_nan=False)] * 3).map(np.array)


def test_drag_only_fall_matches_tanh_closed_form():
    # from rest, outside the table: v(t) = v_t tanh(g t / v_t), fallen d(t) = v_t^2 / g ln cosh(g t / v_t)
    flight = simulate_flight([2.0, 0.0, 3.0], [0.0, 0.0, 0.0], NO_SPIN, P, t_max=0.8)
    v_t = np.sqrt(GRAVITY / P.k_drag)
    t = flight.times
    v_exact = v_t * np.tanh(GRAVITY * t / v_t)
    d_exact = v_t**2 / GRAVITY * np.log(np.cosh(GRAVITY * t / v_t))
    assert flight.events == []  # 0.8 s fall from 3 m does not reach the floor
    np.testing.assert_allclose(-flight.velocities[:, 2], v_exact, atol=1e-9)  # RK4 at 1 ms: ~1e-12
    np.testing.assert_allclose(3.0 - flight.positions[:, 2], d_exact, atol=1e-9)
    np.testing.assert_allclose(flight.positions[:, :2], [[2.0, 0.0]] * len(t), atol=0)


def test_no_drag_no_spin_is_a_parabola():
    vacuum = replace(P, drag_coefficient=0.0, magnus_coefficient=0.0)
    p0, v0 = np.array([1.2, 0.3, 0.5]), np.array([1.0, -2.0, 3.0])
    flight = simulate_flight(p0, v0, [10.0, 50.0, -30.0], vacuum, t_max=0.5)
    t = flight.times[:, None]
    exact = p0 + v0 * t + 0.5 * np.array([0, 0, -GRAVITY]) * t**2
    np.testing.assert_allclose(flight.positions, exact, atol=1e-12)  # RK4 is exact on quadratics


def test_bounce_vertical_restitution():
    v_out, w_out = bounce([0.0, 0.0, -3.0], NO_SPIN, P)
    np.testing.assert_allclose(v_out, [0.0, 0.0, 3.0 * P.table_restitution], atol=1e-15)
    np.testing.assert_allclose(w_out, NO_SPIN, atol=1e-15)


def test_topspin_speeds_up_backspin_slows():
    # ball moving -y: topspin has w_x > 0 (the bottom moves backwards relative to the centre). With
    # mu = 0.25 the spinless ball ends rolling; the spinning ones slide throughout
    params = replace(P, table_friction=0.25)
    v = np.array([0.0, -3.0, -3.0])
    top, _ = bounce(v, [400.0, 0.0, 0.0], params)
    none, _ = bounce(v, NO_SPIN, params)
    back, _ = bounce(v, [-400.0, 0.0, 0.0], params)
    assert -top[1] > 3.0 > -none[1] > -back[1]


def test_sliding_bounce_matches_nakashima_friction():
    # no spin, sliding throughout: the horizontal speed drops by mu (1 + e) |v_z|
    v_out, w_out = bounce([0.0, -5.0, -2.0], NO_SPIN, P)
    e, mu, r = P.table_restitution, P.table_friction, P.radius
    assert v_out[1] == pytest.approx(-5.0 + mu * (1 + e) * 2.0, abs=1e-12)
    # the friction impulse m dv at lever r on I = 2/3 m r^2 gives topspin (w_x > 0 for -y travel)
    assert w_out[0] == pytest.approx(1.5 * (v_out[1] + 5.0) / r, abs=1e-9) and w_out[0] > 0


def test_rolling_condition_zero_slip_after_bounce():
    grippy = replace(P, table_friction=2.0)  # friction would reverse the slip: alpha is capped at 2/5
    v_out, w_out = bounce([1.0, -4.0, -3.0], [50.0, 20.0, 5.0], grippy)
    slip = v_out[:2] + grippy.radius * np.array([-w_out[1], w_out[0]])
    np.testing.assert_allclose(slip, 0.0, atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(v=vec(-10, 10), w=vec(-600, 600), e=st.floats(0.3, 1.0), mu=st.floats(0.0, 1.5))
def test_bounce_matches_nakashima_matrix_form(v, w, e, mu):
    v[2] = -abs(v[2]) - 0.1
    params = replace(P, table_restitution=e, table_friction=mu)
    r = params.radius
    slip = np.hypot(v[0] - r * w[1], v[1] + r * w[0])
    a = min(mu * (1 + e) * abs(v[2]) / slip, 0.4) if slip > 0 else 0.4
    # Nakashima et al. 2010: v' = A_v v + B_v w, w' = A_w v + B_w w
    A_v = np.diag([1 - a, 1 - a, -e])
    B_v = np.array([[0, a * r, 0], [-a * r, 0, 0], [0, 0, 0]])
    A_w = np.array([[0, -1.5 * a / r, 0], [1.5 * a / r, 0, 0], [0, 0, 0]])
    B_w = np.diag([1 - 1.5 * a, 1 - 1.5 * a, 1])
    v_out, w_out = bounce(v, w, params)
    np.testing.assert_allclose(v_out, A_v @ v + B_v @ w, atol=1e-9)
    np.testing.assert_allclose(w_out, A_w @ v + B_w @ w, atol=1e-6)


def kinetic_energy(v, w, params):
    inertia = 2 / 3 * params.mass * params.radius**2
    return 0.5 * params.mass * np.sum(v**2, -1) + 0.5 * inertia * np.sum(w**2, -1)


@settings(max_examples=300, deadline=None)
@given(v=vec(-15, 15), w=vec(-800, 800), e=st.floats(0.0, 1.0), mu=st.floats(0.0, 3.0))
def test_bounce_never_gains_energy(v, w, e, mu):
    v[2] = -abs(v[2])
    params = replace(P, table_restitution=e, table_friction=mu)
    v_out, w_out = bounce(v, w, params)
    assert kinetic_energy(v_out, w_out, params) <= kinetic_energy(v, w, params) * (1 + 1e-12) + 1e-15


@settings(max_examples=200, deadline=None)
@given(v=vec(-15, 15), w=vec(-800, 800), n=vec(-1, 1), vp=vec(-5, 5))
def test_paddle_never_gains_energy_in_the_paddle_frame(v, w, n, vp):
    if np.linalg.norm(n) < 1e-3:
        n = np.array([0.0, 0.0, 1.0])
    n = n / np.linalg.norm(n)
    v_out, w_out = paddle_impact(v, w, n, vp, P)
    assert kinetic_energy(v_out - vp, w_out, P) <= kinetic_energy(v - vp, w, P) * (1 + 1e-12) + 1e-15


@settings(max_examples=25, deadline=None)
@given(v0=vec(-8, 8), w0=vec(-500, 500), p0=vec(-0.5, 0.5))
def test_flight_never_gains_mechanical_energy(v0, w0, p0):
    # away from contacts (the table is far below), drag only removes energy and Magnus does no work
    flight = simulate_flight(p0 + [0, 0, 5.0], v0, w0, P, t_max=0.5)
    energy = 0.5 * np.sum(flight.velocities**2, 1) + GRAVITY * flight.positions[:, 2]
    assert np.all(np.diff(energy) <= 1e-9)


def test_bounce_event_on_the_table_then_floor():
    flight = simulate_flight([0.0, 1.8, 0.3], [0.3, -8.0, 1.0], NO_SPIN, P)
    kinds = [e.kind for e in flight.events]
    assert kinds == ["bounce", "floor"]
    hit = flight.events[0]
    assert hit.side == "-y" and hit.position[2] == P.radius
    assert flight.events[1].position[2] == pytest.approx(FLOOR_Z + P.radius, abs=1e-6)
    # the sample at the bounce instant is there twice: arrival (falling) and departure (rising)
    i = np.flatnonzero(flight.times == hit.time)
    assert len(i) == 2 and flight.velocities[i[0], 2] < 0 < flight.velocities[i[1], 2]


def test_net_event_stops_the_ball():
    flight = simulate_flight([0.1, 0.5, 0.1], [0.0, -5.0, 0.0], NO_SPIN, P)
    assert [e.kind for e in flight.events] == ["net"]
    net = flight.events[0]
    assert abs(net.position[1]) < 1e-5 and 0 < net.position[2] < NET_HEIGHT + P.radius
    assert flight.times[-1] == net.time


def test_ball_over_the_net_beside_the_posts_passes():
    flight = simulate_flight([1.2, 0.5, 0.1], [0.0, -5.0, 0.0], NO_SPIN, P, t_max=0.3)
    assert "net" not in [e.kind for e in flight.events]


def test_stop_at_plane_refines_onto_the_plane():
    flight = simulate_flight([0.0, 1.8, 0.3], [0.3, -8.0, 1.0], NO_SPIN, P, stop=stop_at_y(-1.6))
    assert [e.kind for e in flight.events] == ["bounce", "stop"]
    assert flight.positions[-1, 1] == pytest.approx(-1.6, abs=1e-6)


@settings(max_examples=100, deadline=None)
@given(vx=st.floats(-2, 2), vy=st.floats(3, 12), vz=st.floats(-3, 3), w=vec(-300, 300),
       ox=st.floats(-3, 3), oy=st.floats(-15, -5), oz=st.floats(-1, 4))
def test_paddle_for_outgoing_round_trip(vx, vy, vz, w, ox, oy, oz):
    v_in, v_out = np.array([vx, vy, vz]), np.array([ox, oy, oz])
    n, vp = paddle_for_outgoing(v_in, v_out, P, w_in=w)
    assert np.linalg.norm(n) == pytest.approx(1.0)
    np.testing.assert_allclose(np.cross(n, vp), 0.0, atol=1e-9)  # paddle moves along its normal
    v_back, _ = paddle_impact(v_in, w, n, vp, P)
    np.testing.assert_allclose(v_back, v_out, atol=1e-7)  # root solves the unit normal to ~1e-9


@pytest.mark.parametrize("p_hit, target, w0", [
    ([0.2, 1.9, 0.3], [-0.3, -0.8], [0.0, 0.0, 0.0]),
    ([-0.5, 2.2, 0.1], [0.6, -1.2], [150.0, 0.0, 0.0]),  # topspin from low
    ([0.6, 1.6, 0.5], [-0.6, -0.3], [-120.0, 30.0, 40.0]),  # backspin with side spin, short
])
def test_aim_shot_lands_on_target(p_hit, target, w0):
    v0 = aim_shot(p_hit, target, w0, P)
    flight = simulate_flight(p_hit, v0, w0, P)
    first = flight.events[0]
    assert first.kind == "bounce"
    assert np.linalg.norm(first.position[:2] - target) < 0.01
    assert 3 < np.linalg.norm(v0) < 20


def test_aim_shots_batch_with_per_shot_params():
    rng = np.random.default_rng(3)
    n = 40
    p_hit = np.column_stack([rng.uniform(-0.6, 0.6, n), rng.uniform(1.6, 2.2, n), rng.uniform(0.1, 0.5, n)])
    target = np.column_stack([rng.uniform(-0.6, 0.6, n), rng.uniform(-1.2, -0.3, n)])
    spin = rng.normal(0, 100, (n, 3))
    params = [sample_ball_params(rng, 0.05) for _ in range(n)]
    v0, flight_time = aim_shots(p_hit, target, spin, params, speed_hint=rng.uniform(6, 15, n))
    for k in range(0, n, 4):
        flight = simulate_flight(p_hit[k], v0[k], spin[k], params[k])
        assert flight.events[0].kind == "bounce"
        assert np.linalg.norm(flight.events[0].position[:2] - target[k]) < 0.01
        assert flight.events[0].time == pytest.approx(flight_time[k], abs=2e-3)


def test_sample_ball_params_is_seeded_and_physical():
    a = sample_ball_params(np.random.default_rng(7), 0.2)
    assert a == sample_ball_params(np.random.default_rng(7), 0.2)
    many = [sample_ball_params(np.random.default_rng(s), 0.2) for s in range(200)]
    assert all(p.table_restitution < 1 and p.paddle_restitution < 1 for p in many)
    assert np.std([p.drag_coefficient for p in many]) == pytest.approx(0.2 * P.drag_coefficient, rel=0.25)
