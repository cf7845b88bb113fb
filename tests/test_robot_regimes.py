"""Robot regimes as configuration (pingpong.robot.regimes): parsing, the schema's named regimes, the robot
of a regime's dynamics and the servo's degraded view of the ball."""

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
from workflow_util import ROBOT_LIMITS, ROBOT_URDF

from pingpong.common.artifacts import read_json
from pingpong.common.config import ConfigError, schema_defaults
from pingpong.frames import STRIKE_Y
from pingpong.robot.calibration import (
    PAPER_TABLE2,
    bar_probability,
    calibrate,
    hit_rate_interval,
    knob_grid,
    misfit,
    paper_bar,
    region_stats,
)
from pingpong.robot.controllers import Controller
from pingpong.robot.episode import FRAME_DT, goal_schedule
from pingpong.robot.evaluate import Prediction, SimSettings, episode_params, simulate_hit
from pingpong.robot.flights import HitFlight
from pingpong.robot.model import N_BASE, load_robot, paddle_position, regime_robot
from pingpong.robot.regime_map import alpha_monotone, value_row
from pingpong.robot.regimes import Sensing, map_cells, parse_regime, sense, with_sensing
from pingpong.robot.schemas import REGIME_CALIBRATION, REGIME_CELL

REGIMES = schema_defaults("config/schema.yaml")["robot"]["regimes"]


def straight_flight(x: float, z: float, t_cross: float = 0.7, y0: float = 1.6) -> HitFlight:
    t = np.arange(0.0, t_cross + 0.05, 0.01)
    p = np.column_stack([np.full_like(t, x), y0 + (STRIKE_Y - y0) / t_cross * t, np.full_like(t, z)])
    return HitFlight(t, p, t, p)


def test_the_schema_names_the_paper_fine_hardware_and_calibrated_regimes():
    assert {"paper", "fine", "hardware", "table2"} <= set(REGIMES)
    paper = parse_regime("paper", REGIMES["paper"])
    # the paper's as written: Table 6's arm, 15 m/s^2 and 1.1 m/s base, 0.1 s steps without latency on top
    assert paper.dynamics.arm_accelerations == "table6" and paper.dynamics.base_acceleration_mps2 == 15.0
    assert paper.timing.control_dt_s == 0.1 and paper.timing.latency_frames == 0 and paper.sensing.perfect
    hardware = parse_regime("hardware", REGIMES["hardware"])
    assert hardware.dynamics.base_acceleration_mps2 == 1.0 and hardware.dynamics.base_speed_mps == 1.1
    assert hardware.timing.latency_frames == 10 and hardware.timing.control_dt_s == 0.01


def test_a_calibrated_regime_needs_and_takes_its_calibration():
    with pytest.raises(ConfigError, match="calibrat"):
        parse_regime("table2", REGIMES["table2"])
    calibration = {"sensing": {"noise_m": 0.01, "dropout": 0.1, "delay_frames": 2}, "servo_fit": "paper"}
    regime = parse_regime("table2", REGIMES["table2"], seed=7, calibration=calibration)
    assert regime.sensing == Sensing(0.01, 0.1, 2, 7) and regime.servo_fit == "paper" and regime.calibrated
    # no dynamics knobs: the config's dynamics
    assert regime.dynamics == parse_regime("paper", REGIMES["paper"]).dynamics
    calibration["dynamics"] = {"base_speed_mps": 1.4, "base_start_x_m": 0.05}
    regime = parse_regime("table2", REGIMES["table2"], seed=7, calibration=calibration)
    assert regime.dynamics.base_speed_mps == 1.4 and regime.dynamics.base_start_x_m == 0.05
    assert regime.dynamics.base_acceleration_mps2 == REGIMES["table2"]["dynamics"]["base_acceleration_mps2"]


def test_unknown_or_missing_keys_are_config_errors():
    spec = {**REGIMES["paper"], "dynamics": {**REGIMES["paper"]["dynamics"], "base_jerk": 3.0}}
    with pytest.raises(ConfigError, match="base_jerk"):
        parse_regime("mine", spec)
    spec = {**REGIMES["paper"], "timing": {"control_dt_s": 0.1}}
    with pytest.raises(ConfigError, match="timing"):
        parse_regime("mine", spec)


def test_the_regime_robot_has_the_regimes_base_limits_and_arm_set():
    hardware = parse_regime("hardware", REGIMES["hardware"])
    robot = regime_robot(ROBOT_URDF, ROBOT_LIMITS, hardware.dynamics)
    drake = load_robot(ROBOT_URDF, ROBOT_LIMITS, "drake")
    assert np.all(robot.a_max[:N_BASE] == 1.0) and np.all(robot.v_max[:N_BASE] == 1.1)
    np.testing.assert_array_equal(robot.a_max[N_BASE:], drake.a_max[N_BASE:])
    paper = regime_robot(ROBOT_URDF, ROBOT_LIMITS, parse_regime("paper", REGIMES["paper"]).dynamics)
    np.testing.assert_array_equal(paper.a_max, load_robot(ROBOT_URDF, ROBOT_LIMITS).a_max)
    np.testing.assert_array_equal(paper.q_home, load_robot(ROBOT_URDF, ROBOT_LIMITS).q_home)
    # where the base waits: the home's base x moves, the paddle with it, the arm's posture stays
    moved = regime_robot(ROBOT_URDF, ROBOT_LIMITS, replace(paper_dynamics := parse_regime(
        "paper", REGIMES["paper"]).dynamics, base_start_x_m=0.1))
    np.testing.assert_allclose(paddle_position(moved, moved.q_home) - paddle_position(paper, paper.q_home),
                               [0.1, 0.0, 0.0], atol=1e-12)
    np.testing.assert_array_equal(moved.q_home[1:], paper.q_home[1:])
    with pytest.raises(ValueError, match="outside"):
        regime_robot(ROBOT_URDF, ROBOT_LIMITS, replace(paper_dynamics, base_start_x_m=5.0))


def test_sensing_is_seeded_per_flight_and_scales_the_same_draws():
    t = np.arange(50) * FRAME_DT
    seen = np.column_stack([np.zeros(50), 1.6 - 5 * t, 0.2 + 0 * t])
    assert sense(t, seen, Sensing()) is seen
    a = sense(t, seen, Sensing(noise_m=0.01, seed=3))
    np.testing.assert_array_equal(a, sense(t, seen.copy(), Sensing(noise_m=0.01, seed=3)))
    b = sense(t, seen, Sensing(noise_m=0.02, seed=3))
    np.testing.assert_allclose(b - seen, 2 * (a - seen))  # common random numbers
    assert not np.allclose(a, sense(t, seen, Sensing(noise_m=0.01, seed=4)))
    dropped = sense(t, seen, Sensing(dropout=0.5, seed=3))
    assert 10 < np.isnan(dropped[:, 0]).sum() < 40
    assert np.isnan(sense(t, seen, Sensing(dropout=1.0))).all()


def test_servo_delay_and_noise_degrade_the_servo_goals():
    regime = parse_regime("paper", REGIMES["paper"])
    flight = straight_flight(0.3, 0.3)
    exact = goal_schedule(flight.times, flight.positions, 0.7, None, episode_params(regime))
    delayed = goal_schedule(flight.times, flight.positions, 0.7, None,
                            episode_params(with_sensing(regime, delay_frames=5)))
    # the same goal times (the delay is in what is seen, not when the goal is used), older data
    np.testing.assert_array_equal(exact.times, delayed.times)
    blind = goal_schedule(flight.times, flight.positions, 0.7, None,
                          episode_params(with_sensing(regime, dropout=1.0)))
    assert blind.servo_no_estimate == len(exact.times) and np.isinf(blind.first_servo)
    robot = regime_robot(ROBOT_URDF, ROBOT_LIMITS, regime.dynamics)
    clean = simulate_hit(robot, flight, Prediction(np.arange(-30, 1), np.full(31, 0.3)), Controller("servo"),
                         SimSettings(episode_params(replace(regime, servo_fit="paper"))))
    noisy = simulate_hit(robot, flight, Prediction(np.arange(-30, 1), np.full(31, 0.3)), Controller("servo"),
                         SimSettings(episode_params(replace(with_sensing(regime, noise_m=0.05),
                                                            servo_fit="paper"))))
    assert clean["end_distance_m"] < 0.01 < noisy["end_distance_m"]


# ---------------------------------------------------------------- calibration to the paper's Table 2

def synthetic_sim(knobs: dict, n: int = 400) -> pd.DataFrame:
    """A stand-in for servo's episodes whose hit rate and end distance follow the knobs (common random
    numbers: the same draws for every knob setting)."""
    rng = np.random.default_rng(0)
    regions = np.repeat(["left", "centre", "right"], n)
    base = np.repeat([0.05, 0.02, 0.04], n)
    spread = base + 2.0 * knobs["noise_m"] + 0.01 * knobs["delay_frames"] + 0.05 * knobs["dropout"]
    spread = spread * (1.5 if knobs["servo_fit"] == "paper" else 1.0)
    distance = spread * np.abs(rng.standard_normal(3 * n))
    return pd.DataFrame({"region": regions, "hit_ball": distance <= 0.08, "end_distance_m": distance})


def test_the_calibration_recovers_known_knobs_from_their_synthetic_table():
    truth = {"noise_m": 0.02, "delay_frames": 5, "dropout": 0.0, "servo_fit": "model"}
    target_stats = region_stats(synthetic_sim(truth)).set_index("region")
    target = {r: (target_stats.loc[r, "hit_rate"] * 1000, 1000, target_stats.loc[r, "end_distance_cm"], 1.0)
              for r in PAPER_TABLE2}
    grid = {"noise_m": [0.0, 0.01, 0.02, 0.04], "delay_frames": [0, 5, 10], "dropout": [0.0, 0.5],
            "servo_fit": ["model", "paper"]}
    knobs, table = calibrate(synthetic_sim, grid, target)
    assert knobs == truth and len(table) == 48 and table["misfit"].min() == pytest.approx(0.0, abs=1e-9)


def test_the_misfit_weighs_hit_rates_by_8_points_and_distances_by_the_papers_half_std():
    stats = pd.DataFrame({"region": ["left", "centre", "right"], "n": [41, 81, 101],
                          "hit_rate": [24 / 41 + 0.08, 60 / 81, 60 / 101],
                          "end_distance_cm": [12.82, 6.26 + 1.93, 10.13]})
    assert misfit(stats) == pytest.approx(2.0)
    bar = paper_bar(stats.assign(hits=[0, 0, 0]))
    assert bar["hit_rate_within"].tolist() == [True, True, True]  # 8 points is within
    assert bar["end_distance_within"].tolist() == [True, True, True]
    assert not paper_bar(stats.assign(hits=0, hit_rate=[0.3, 0.74, 0.59]))["hit_rate_within"].iloc[0]


def test_the_knob_grid_spans_the_knobs_it_names_sensing_fit_and_reach():
    grid = {"noise_m": [0.0, 0.01], "servo_fit": ["paper"], "base_speed_mps": [1.1, 1.5],
            "base_start_x_m": [0.0, 0.05, 0.1], "splits": ["train"]}
    points = knob_grid(grid)
    assert len(points) == 12
    assert set(points[0]) == {"noise_m", "servo_fit", "base_speed_mps", "base_start_x_m"}
    assert points[0] == {"noise_m": 0.0, "servo_fit": "paper", "base_speed_mps": 1.1, "base_start_x_m": 0.0}
    assert points[-1]["base_start_x_m"] == 0.1 and points[-1]["noise_m"] == 0.01


def test_hit_rate_intervals_are_clopper_pearson():
    from scipy.stats import beta
    low, high = hit_rate_interval(7, 17)
    assert low == pytest.approx(beta.ppf(0.025, 7, 11)) and high == pytest.approx(beta.ppf(0.975, 8, 10))
    assert hit_rate_interval(0, 10)[0] == 0.0 and hit_rate_interval(10, 10)[1] == 1.0
    stats = pd.DataFrame({"region": ["left", "centre", "right"], "n": [17, 38, 43], "hits": [7, 27, 17],
                          "hit_rate": [7 / 17, 27 / 38, 17 / 43], "end_distance_cm": [14.7, 5.9, 12.9]})
    bar = paper_bar(stats).set_index("region")
    # the default run of fb04da0: right 17/43 = 40 % (CI 25-56 %) excludes the paper's 59 %; left 7/17
    # (18-67 %) does not
    assert bar.loc["left", "paper_in_ci95"] and not bar.loc["right", "paper_in_ci95"]
    assert (bar["hit_pct_ci95_low"] <= bar["hit_pct"]).all()
    assert (bar["hit_pct"] <= bar["hit_pct_ci95_high"]).all()


def test_the_bar_probability_is_the_binomial_chance_of_landing_within_the_points():
    rng = np.random.default_rng(0)
    for n, rate in [(17, 24 / 41), (38, 60 / 81), (43, 60 / 101), (400, 0.5)]:
        draws = rng.binomial(n, rate, 200_000) / n
        simulated = np.mean(np.abs(draws - rate) <= 0.08 + 1e-12)
        assert bar_probability(n, rate) == pytest.approx(simulated, abs=0.005)
    # the bounds are inclusive: 21 and 29 of 50 are 8 points from 50 %
    from scipy.stats import binom
    assert bar_probability(50, 0.5) == pytest.approx(binom.cdf(29, 50, 0.5) - binom.cdf(20, 50, 0.5))
    assert bar_probability(400, 0.5) > 0.99 and bar_probability(17, 24 / 41) < 0.6


# ---------------------------------------------------------------- the regime map

def test_map_cells_are_the_named_regimes_then_the_base_over_the_grid():
    cells = map_cells(REGIMES, ["paper", "table2"], "fine",
                      {"base_acceleration_mps2": [1.0, 15.0], "latency_frames": [0, 10]})
    assert list(cells)[:2] == ["paper", "table2"] and len(cells) == 6
    cell = cells["fine__base_acceleration_mps2=1__latency_frames=10"]
    regime = parse_regime("x", cell)
    assert regime.dynamics.base_acceleration_mps2 == 1.0 and regime.timing.latency_frames == 10
    assert regime.timing.control_dt_s == REGIMES["fine"]["timing"]["control_dt_s"]
    assert REGIMES["fine"]["dynamics"]["base_acceleration_mps2"] == 15.0  # the config is not changed
    assert cells["table2"]["calibration_of"] == "table2" and "calibration_of" not in cells["paper"]
    with pytest.raises(ValueError, match="no key"):
        map_cells(REGIMES, [], "fine", {"base_jerk": [1.0]})


def test_the_values_intervals_are_paired_over_the_same_hits():
    rng = np.random.default_rng(0)
    base = rng.random(200) < 0.6
    results = {"servo": {"hit": base.tolist()}, "anticipatory": {"hit": base.tolist()},
               "better": {"hit": (base | (rng.random(200) < 0.1)).tolist()}}
    same = value_row(results, "servo", "anticipatory", rng, 500)
    assert same == {"value": 0, "ci95_low": 0.0, "ci95_high": 0.0}  # paired: identical outcomes, no spread
    better = value_row(results, "servo", "better", rng, 500)
    assert better["value"] > 0 and 0 <= better["ci95_low"] <= better["value"] <= better["ci95_high"]


def test_alpha_monotone_tells_an_interior_optimum():
    rows = [{"alpha1": a1, "alpha2": a2, "hits": 10 + a1 + a2} for a1 in (0, 0.5, 1) for a2 in (0, 0.5, 1)]
    assert alpha_monotone(rows)
    rows = [{**r, "hits": 12 if (r["alpha1"], r["alpha2"]) == (0.5, 0.5) else 10} for r in rows]
    assert not alpha_monotone(rows)


def test_tiny_run_regime_tables_are_consistent(tiny_run):
    table = pd.read_csv(tiny_run / "reports/tables/robot_regimes.csv")
    robot = pd.read_csv(tiny_run / "reports/tables/robot.csv")
    defaults = schema_defaults("config/schema.yaml")["robot"]["regime_map"]
    assert len(table) == len(defaults["named"]) + np.prod([len(v) for v in defaults["axes"].values()])
    assert (table["anticipation_value"] == table["hits_anticipatory"] - table["hits_servo"]).all()
    assert (table["anticipation_ci95_low"] <= table["anticipation_value"]).all()
    assert (table["anticipation_value"] <= table["anticipation_ci95_high"]).all()
    # the configured regime's cell is Tables 2-4's run: the same hits
    paper = table.set_index("cell").loc["paper"]
    all_rows = robot[robot["region"] == "all"].set_index("controller")
    for name in ("servo", "anticipatory", "uncertainty_aware"):
        assert paper[f"hits_{name}"] == all_rows.loc[name, "hits"]
    calibration = pd.read_csv(tiny_run / "reports/tables/robot_regime_calibration.csv")
    assert set(calibration["region"]) <= set(PAPER_TABLE2) and (calibration["regime"] == "table2").all()
    assert (calibration["hit_pct_ci95_low"] <= calibration["hit_pct"]).all()
    assert (calibration["hit_pct"] <= calibration["hit_pct_ci95_high"]).all()
    inside = calibration["paper_hit_pct"].between(calibration["hit_pct_ci95_low"],
                                                  calibration["hit_pct_ci95_high"])
    assert (calibration["paper_in_ci95"] == inside).all()
    assert calibration["bar_probability_if_calibrated"].between(0, 1).all()
    # the calibrated reach reached the cell: its dynamics are the calibration artifact's
    fitted = read_json(tiny_run / "processed/robot/regime_table2.json", REGIME_CALIBRATION)
    cell = read_json(tiny_run / "processed/robot/regime_map/table2.json", REGIME_CELL)
    assert fitted["dynamics"] and all(cell["dynamics"][k] == v for k, v in fitted["dynamics"].items())
    assert fitted["splits"] == ["train", "calibration"]
    for name in defaults["named"]:
        assert (tiny_run / f"reports/figures/robot_alpha_surface_{name}.png").stat().st_size > 0
    assert (tiny_run / "reports/figures/robot_regime_map.png").stat().st_size > 0


# ---------------------------------------------------------------- the servo's ball

def test_the_servo_ball_is_fitted_on_half_the_real_flights_with_the_published_lift():
    from pingpong.robot.servo import MODEL_BALL
    from pingpong.robot.servo_ball import (
        PUBLISHED_LIFT,
        fit_servo_ball,
        real_flight_in_table_frame,
        split_flights,
    )
    from pingpong.twin.realdata import load_real_flights

    flights = load_real_flights("data/realdata/mpi_ball_gun")
    fit_half, held_out = split_flights(flights)
    assert not {f["name"] for f in fit_half} & {f["name"] for f in held_out}
    assert len(fit_half) + len(held_out) == len(flights)
    params = fit_servo_ball(fit_half)["params"]
    lift = params["magnus_coefficient"]
    assert lift == PUBLISHED_LIFT["magnus_coefficient"] != MODEL_BALL.magnus_coefficient  # not the twin's
    assert 0.3 < params["drag_coefficient"] < 0.7 and 0.8 < params["table_restitution"] < 1.0
    times, positions = real_flight_in_table_frame(held_out[0])
    assert times[0] == 0 and positions[:, 2].min() < 0.05
    assert positions[0, 1] > 0 > STRIKE_Y > positions[-1, 1]  # towards the robot, past the strike line


def test_cached_episodes_equal_fresh_ones_and_are_shared_across_equal_goals():
    """SimSettings' episode cache: a sweep's candidates that move the robot alike run once, with the same
    results as uncached episodes (uncertainties differ between the prediction kinds, goals do not)."""
    from pingpong.robot.evaluate import simulate_hits
    regime = parse_regime("fine", REGIMES["fine"])
    robot = regime_robot(ROBOT_URDF, ROBOT_LIMITS, regime.dynamics)
    flights = [straight_flight(x, 0.25, t) for x, t in [(0.0, 0.6), (0.5, 0.45), (-0.6, 0.7)]]
    hits = pd.DataFrame({"session": "s", "rally": 0, "hit": [0, 1, 2], "region": ["centre", "right", "left"],
                         "strike_x": [0.0, 0.5, -0.6], "strike_z": 0.25})
    frames = np.arange(-30, 1)
    plain = [Prediction(frames, np.full(31, x)) for x in (0.05, 0.5, -0.4)]
    estimated = [Prediction(p.frames, p.strike_x, np.linspace(0.01, 0.1, 31)) for p in plain]
    controllers = [Controller("servo"), Controller("a", 1.0, 1.0),
                   Controller("u", 0.6, 1.0, skip_centre=True), Controller("u", 1.0, 1.0, skip_centre=True),
                   Controller("c", 1.0, 1.0, confidence=(0.2, 0.3))]
    shared = SimSettings(episode_params(regime))
    for controller in controllers:
        for preds in (estimated,) if controller.confidence else (plain, estimated):
            cached = simulate_hits(robot, hits, flights, preds, controller, shared)
            fresh = simulate_hits(robot, hits, flights, preds, controller,
                                  SimSettings(episode_params(regime)))
            pd.testing.assert_frame_equal(cached, fresh)
    # servo, and the ramp whose u_full is above every uncertainty (alpha 1: basic anticipation), repeat
    # others; skip_centre makes the centre hit servo's; the two kinds share their goals
    assert len(shared.episodes) < 2 * len(controllers) * len(flights) // 2
    assert len(shared.schedules) == len(flights)
