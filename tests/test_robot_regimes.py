"""Robot regimes as configuration (pingpong.robot.regimes): parsing, the schema's named regimes, the robot
of a regime's dynamics and the servo's degraded view of the ball."""

from dataclasses import replace

import numpy as np
import pytest
from workflow_util import ROBOT_LIMITS, ROBOT_URDF

from pingpong.common.config import ConfigError, schema_defaults
from pingpong.frames import STRIKE_Y
from pingpong.robot.controllers import Controller
from pingpong.robot.episode import FRAME_DT, goal_schedule
from pingpong.robot.evaluate import Prediction, SimSettings, episode_params, simulate_hit
from pingpong.robot.flights import HitFlight
from pingpong.robot.model import N_BASE, load_robot, regime_robot
from pingpong.robot.regimes import Sensing, parse_regime, sense, with_sensing

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
