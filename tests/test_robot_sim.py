"""The robot stage: flights from the filtered ball, the controllers' alpha schedules, the sweep, the
report's statistics, and the torque-derived accelerations against a hand computation."""

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from workflow_util import ROBOT_LIMITS, ROBOT_URDF

from pingpong.frames import STRIKE_Y
from pingpong.reports.robot import bootstrap_hit_difference, mcnemar_exact, robot_table
from pingpong.robot.control import ControlParams
from pingpong.robot.controllers import CONTROLLERS, Controller, Tuning, alpha_grid, controller_names
from pingpong.robot.episode import EpisodeParams
from pingpong.robot.evaluate import (
    Prediction,
    SimSettings,
    confidence_ramp,
    simulate_hit,
    step_alphas,
)
from pingpong.robot.flights import HitFlight, hit_flight
from pingpong.robot.model import N_BASE, load_robot, worst_case_accelerations
from pingpong.robot.sweep import best_cell, choose_controller, sweep

ROBOT = load_robot(ROBOT_URDF, ROBOT_LIMITS)  # the paper's Table 6 accelerations
DRAKE = load_robot(ROBOT_URDF, ROBOT_LIMITS, "drake")  # Drake's, 7-635x lower
FRAMES = np.arange(-30, 1)
# the fine timing (config robot.timings.fine): 10 ms steps, 100 ms latency on top, a goal every frame
FINE = SimSettings(EpisodeParams(anticipation_period_frames=1, latency_frames=10, servo_fit="paper",
                                 control=ControlParams(dt=0.01)))
PAPER = SimSettings(EpisodeParams(servo_fit="paper"))  # the paper's timing and servo fit


def straight_flight(x: float, z: float, t_cross: float, y0: float = 1.6) -> HitFlight:
    """A ball at constant velocity along -y (no gravity, no bounce), seen as it is: the paper's quadratic
    servo fit is exact on it (the model fit assumes gravity and drag)."""
    t = np.arange(0.0, t_cross + 0.05, 0.01)
    p = np.column_stack([np.full_like(t, x), y0 + (STRIKE_Y - y0) / t_cross * t, np.full_like(t, z)])
    return HitFlight(t, p, t, p)


def perfect(x: float, uncertainty: float | None = None) -> Prediction:
    n = len(FRAMES)
    return Prediction(FRAMES, np.full(n, x), None if uncertainty is None else np.full(n, uncertainty))


# ---------------------------------------------------------------- flights

def test_far_hitters_flight_is_mirrored_gaps_dropped_and_cut_past_the_strike_line():
    t_hit = 1_000_000_000
    time_ns = t_hit + 10_000_000 * np.arange(-5, 120)
    t = (time_ns - t_hit) / 1e9
    ball = pd.DataFrame({"time_ns": time_ns, "x": 0.1 + 0.2 * t, "y": -1.5 + 5.0 * t, "z": 0.3 + 0 * t})
    ball.loc[10, "x"] = np.nan  # a frame without a ball
    times, positions = hit_flight(ball, t_hit, "far")
    assert times[0] == 0.0 and np.all(np.diff(times) > 0) and 0.05 not in times
    assert np.allclose(positions[:, 0], -(0.1 + 0.2 * times))
    assert np.allclose(positions[:, 1], 1.5 - 5 * times)
    assert positions[-1, 1] <= STRIKE_Y < positions[-2, 1]  # one sample past the line, no more
    near_times, near = hit_flight(ball.assign(y=1.5 - 5.0 * t), t_hit, "near")
    assert np.allclose(near, positions * [-1, 1, 1]) and np.array_equal(near_times, times)


# ---------------------------------------------------------------- controllers

def test_servo_hits_a_straight_ball_to_a_reachable_point():
    for x, z in [(0.3, 0.3), (-0.4, 0.2), (0.0, 0.1)]:
        out = simulate_hit(ROBOT, straight_flight(x, z, 0.7), perfect(x), Controller("servo"), PAPER)
        assert out["hit"] and out["end_distance_m"] < 0.01  # the servo's estimate is exact here
        assert out["limits_ok"] and not out["anticipated"]


def test_perfect_anticipation_hits_far_goals_that_servoing_alone_misses():
    # the slow regime (Drake's accelerations, the fine timing's 100 ms latency on top)
    flights = [(0.6, 0.2), (-0.7, 0.2), (0.65, 0.15), (-0.6, 0.25)]
    hits = {"servo": 0, "anticipatory": 0}
    for x, z in flights:
        for controller in (Controller("servo"), Controller("anticipatory", 1.0, 1.0)):
            out = simulate_hit(DRAKE, straight_flight(x, z, 0.45), perfect(x), controller, FINE)
            assert out["limits_ok"]
            hits[controller.name] += out["hit"]
    assert hits["servo"] == 0 and hits["anticipatory"] == len(flights)


def test_step_alphas_follow_each_controllers_rule():
    params = FINE.episode
    times = np.round(np.arange(-0.1, 0.5, 0.01), 10)
    x = np.where(FRAMES < -15, 0.6, 0.1)  # outside the centre until frame -16, then inside
    uncertainty = np.where(FRAMES < -5, 0.30, 0.05)
    prediction = Prediction(FRAMES, x, uncertainty)
    first_servo = 0.2
    latest = lambda t: FRAMES[FRAMES * 0.01 + 0.1 <= t + 1e-12][-1]  # noqa: E731 latest usable frame
    aware = step_alphas(times, first_servo, prediction, Controller("u", 0.7, 0.4, skip_centre=True), params)
    scaled = step_alphas(times, first_servo, prediction, Controller("c", 1, 1, confidence=(0.1, 0.2)), params)
    for t, a, c in zip(times, aware, scaled, strict=True):
        if t >= first_servo - 1e-12:
            assert a == c == 1.0
            continue
        frame = latest(t)
        assert a == pytest.approx((0.7 if t < -1e-12 else 0.4) * (frame < -15))
        assert c == (1.0 if frame >= -5 else 0.0)


def test_paper_timing_moves_on_the_predictions_of_t_minus_10_and_0_only():
    params = SimSettings().episode  # the paper's: 0.1 s steps, no latency on top, goals at 10 Hz
    times = np.array([-0.1, 0.0, 0.1, 0.2])
    x = np.where(FRAMES == -10, 0.6, np.where(FRAMES == 0, -0.6, 0.0))  # centre everywhere else
    aware = step_alphas(times, 0.1, Prediction(FRAMES, x), Controller("u", 0.6, 1.0, skip_centre=True),
                        params)
    # alpha1 on t = -10's prediction over [-0.1, 0), alpha2 on t = 0's over [0, 0.1), then the servo
    np.testing.assert_array_equal(aware, [0.6, 1.0, 1.0, 1.0])
    early = step_alphas(times, 0.1, Prediction(FRAMES, np.where(FRAMES == -10, 0.0, 0.6)),
                        Controller("u", 0.6, 1.0, skip_centre=True), params)
    np.testing.assert_array_equal(early, [0.0, 1.0, 1.0, 1.0])  # t = -10 in the centre: no move before 0


@settings(max_examples=100)
@given(st.floats(0.0, 1.0), st.floats(0.0, 1.0), st.lists(st.floats(0.0, 2.0), min_size=2, max_size=20))
def test_confidence_ramp_is_a_monotone_map_into_0_1(a, b, u):
    u_full, u_zero = min(a, b), max(a, b)
    u = np.sort(np.array(u))
    alpha = confidence_ramp(u, u_full, u_zero)
    assert np.all((alpha >= 0) & (alpha <= 1)) and np.all(np.diff(alpha) <= 1e-12)
    assert np.all(alpha[u <= u_full] == 1.0) and np.all(alpha[u > u_zero] == 0.0)


# ---------------------------------------------------------------- sweep

def test_best_cell_maximises_hits_then_minimises_distance_then_takes_the_first():
    table = pd.DataFrame({"hits": [3, 5, 5, 5, 1], "mean_end_distance_m": [0.01, 0.2, 0.1, 0.1, np.nan]})
    assert best_cell(table) == 2


def test_sweep_picks_the_alphas_that_hit_the_far_goals():
    goals = [(0.6, 0.2), (-0.7, 0.2), (0.3, 0.3)]
    flights = [straight_flight(x, z, 0.45 if abs(x) > 0.5 else 0.7) for x, z in goals]
    hits = pd.DataFrame({"session": "s", "rally": 0, "hit": range(3), "region": "x", "strike_x": 0.0,
                         "strike_z": 0.0})
    candidates = alpha_grid("u", Tuning([0.0, 1.0], []))
    chosen, table = sweep(DRAKE, hits, flights, [perfect(x) for x, _ in goals], candidates, FINE)
    assert len(table) == 4 and table["hits"].max() == 3
    assert table.loc[(table["alpha1"] == 0) & (table["alpha2"] == 0), "hits"].item() == 1  # servo: slow only
    row = table[(table["alpha1"] == chosen.alpha1) & (table["alpha2"] == chosen.alpha2)].iloc[0]
    assert row["hits"] == 3 and chosen.skip_centre


# ---------------------------------------------------------------- report statistics

def test_mcnemar_exact_and_bootstrap_on_closed_forms():
    base = np.array([False] * 5 + [True] * 3)
    better = np.array([True] * 5 + [True] * 3)
    assert mcnemar_exact(base, better) == pytest.approx(2 * 0.5**5)  # 5 discordant pairs, all one way
    assert mcnemar_exact(base, base) == 1.0
    rng = np.random.default_rng(0)
    assert bootstrap_hit_difference(base, base, rng) == (0.0, 0.0)
    low, high = bootstrap_hit_difference(base, better, rng, n_boot=4000)
    assert 0 < low <= 5 <= high <= 8  # the observed +5 lies inside


def test_robot_table_regions_add_up_and_compare_against_servo():
    keys = pd.DataFrame({"session": "s", "rally": 0, "hit": range(6),
                         "region": ["left", "left", "centre", "right", "right", "right"]})
    sim = lambda hit: keys.assign(hit_ball=hit, end_distance_m=np.linspace(0.01, 0.3, 6),  # noqa: E731
                                  limits_ok=True)
    table = robot_table({"servo": sim([1, 0, 1, 0, 0, 0]), "anticipatory": sim([1, 1, 1, 1, 1, 0]),
                         "uncertainty_aware": sim([1, 1, 0, 0, 0, 0]),
                         "confidence_scaled_oracle": sim([1, 1, 1, 1, 1, 1])}, np.random.default_rng(1), 500)
    for _, rows in table.groupby("controller"):
        regions = rows.set_index("region")
        assert regions.loc["all", "total"] == regions.loc[["left", "centre", "right"], "total"].sum() == 6
        assert regions.loc["all", "hits"] == regions.loc[["left", "centre", "right"], "hits"].sum()
    all_rows = table[table["region"] == "all"].set_index("controller")
    assert all_rows.loc["anticipatory", "hits_minus_servo"] == 3
    assert all_rows.loc["anticipatory", "mcnemar_p"] == pytest.approx(0.25)  # 3 discordant, one way
    assert all_rows.loc["servo", "hits_minus_servo"] == 0
    # a confidence-scaled controller is also compared with the paper's uncertainty-aware one: +4, one way
    oracle = all_rows.loc["confidence_scaled_oracle"]
    assert oracle["hits_minus_uncertainty_aware"] == 4
    assert oracle["paper_ua_mcnemar_p"] == pytest.approx(0.125)
    assert 0 < oracle["paper_ua_diff_ci95_low"] <= 4 <= oracle["paper_ua_diff_ci95_high"]
    assert all_rows["hits_minus_uncertainty_aware"].isna().sum() == 3  # the others are not compared
    d = 100 * np.linspace(0.01, 0.3, 6)
    assert all_rows.loc["servo", "end_distance_mean_cm"] == pytest.approx(d.mean())
    assert all_rows.loc["servo", "end_distance_half_std_cm"] == pytest.approx(0.5 * d.std())


# ---------------------------------------------------------------- torque-derived accelerations

def test_derived_accelerations_at_the_upright_arm_match_a_hand_computation():
    """Arm straight up (q = 0), at rest: joints 1 and 7 turn about the vertical, so gravity loads neither and
    the reachable acceleration is tau_max / M_ii, with M_ii = sum over the links it carries of
    izz + m (x^2 + y^2) (every link frame aligned with the table at q = 0; URDF inertials below)."""
    # (mass kg, com x, com y, izz) of links 1..7 and the paddle, from config/robot/iiwa14_ridgeback.urdf
    links = [(5.76, 0, -0.03, 0.0123), (6.35, -0.0003, 0.042, 0.0304), (3.5, 0, 0.03, 0.0076),
             (3.5, 0, -0.034, 0.0164), (3.5, -0.0001, -0.021, 0.00449), (1.8, 0, 0.0004, 0.0047),
             (1.2, 0, 0, 0.001), (0.2, 0, 0, 0.00064)]
    inertia_about_z = [izz + m * (x * x + y * y) for m, x, y, izz in links]
    q0 = np.zeros(ROBOT.model.nq)
    pinned = replace(ROBOT, q_min=q0, q_max=q0)  # every sample is the upright arm
    acc = worst_case_accelerations(pinned, np.random.default_rng(0), n_samples=3, with_velocity=False)
    assert acc["simple_min"][0] == pytest.approx(320.0 / sum(inertia_about_z), rel=1e-9)
    assert acc["simple_min"][6] == pytest.approx(40.0 / sum(inertia_about_z[6:]), rel=1e-9)
    assert acc["coupled_min"][6] == pytest.approx(acc["simple_min"][6], rel=1e-9)  # no coupling about z
    sampled = worst_case_accelerations(ROBOT, np.random.default_rng(1), n_samples=200)
    assert np.all(sampled["coupled_min"] > 0)
    assert np.all(DRAKE.a_max[N_BASE:] < sampled["coupled_min"])  # Drake's are reachable everywhere


def test_controllers_come_from_the_registry():
    assert controller_names(with_uncertainty=True, with_oracle=True) == list(CONTROLLERS)
    assert "confidence_scaled" in CONTROLLERS and "confidence_scaled" not in controller_names(False)
    assert controller_names(True) == [c for c in CONTROLLERS if c != "confidence_scaled_oracle"]
    assert Controller.from_choice(Controller("c", 1.0, 0.5, confidence=(0.1, 0.2)).to_choice()) == \
        Controller("c", 1.0, 0.5, confidence=(0.1, 0.2))
    fixed, table = choose_controller("anticipatory", ROBOT, None, [], [], SimSettings(), [0.5], [0.5])
    assert fixed == Controller("anticipatory", 1.0, 1.0) and table is None
    with pytest.raises(ValueError, match="unknown controller 'nope'; expected one of"):
        choose_controller("nope", ROBOT, None, [], [], SimSettings(), [0.5], [0.5])
