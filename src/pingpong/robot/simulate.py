"""One controller over a run's hits: tuned on the calibration hits where it has a grid, then simulated on
the test hits (the simulate_robot rule); and what robot_scene re-runs of it."""

import numpy as np
import pandas as pd

from pingpong.common.artifacts import read_json
from pingpong.robot.controllers import CONTROLLERS
from pingpong.robot.evaluate import RobotSettings, hit_predictions, sim_settings, simulate_hits
from pingpong.robot.flights import hit_flights
from pingpong.robot.model import Robot, regime_robot
from pingpong.robot.regimes import Regime
from pingpong.robot.schemas import REGIME_CALIBRATION, SERVO_BALL
from pingpong.robot.sweep import choose_controller
from pingpong.twin.ball import BallParams


def final_predictions(predictions: pd.DataFrame) -> pd.DataFrame:
    """The final model's rows of a PREDICTIONS table: what the robot anticipates on."""
    return predictions[predictions["model"] == "final"]


def hit_parts(hits: pd.DataFrame, balls: tuple[dict, dict | None], predictions: pd.DataFrame,
              uncertainty: pd.DataFrame | None, controller: str, max_flight_s: float) -> tuple:
    """(hits, their flights, their predictions) as a controller sees them: with the configured estimator's
    uncertainties only where the controller follows them. balls: (judged, seen) ball tables by session
    (flights.hit_flights)."""
    follows = CONTROLLERS[controller].follows_uncertainty
    return (hits, hit_flights(hits, balls[0], max_flight_s, balls[1]),
            hit_predictions(predictions, hits, uncertainty if follows else None))


def simulate_controller(name: str, robot: Robot, dataset: pd.DataFrame, predictions: pd.DataFrame,
                        balls: tuple[dict, dict | None], uncertainty: pd.DataFrame | None,
                        cfg: RobotSettings, regime: Regime,
                        servo_ball: BallParams | None = None) -> tuple[pd.DataFrame, dict]:
    """(SIM table of the test hits, the CHOICE record: the chosen settings and the calibration sweep).

    dataset: DATASET rows; predictions: the final model's; balls: (judged, seen) session -> ball table
    (flights.hit_flights); uncertainty: the configured estimator's table (None: no estimator); regime: the
    configured one (cfg.resolve); servo_ball: the servo model fit's ball.
    """
    settings = sim_settings(regime, dataset.loc[dataset["split"] == "train", "strike_z"].median(), servo_ball)
    parts = {split: hit_parts(dataset[dataset["split"] == split].reset_index(drop=True), balls, predictions,
                              uncertainty, name, cfg.max_flight_s)
             for split in ("calibration", "test")}
    controller, sweep = choose_controller(name, robot, *parts["calibration"], settings, cfg.alpha_grid,
                                          cfg.confidence_quantiles)
    sim = simulate_hits(robot, *parts["test"], controller, settings)
    choice = {**controller.to_choice(), "anticipation_z_m": settings.anticipation_z,
              "n_calibration_hits": len(parts["calibration"][0]),
              "sweep": [] if sweep is None else sweep.replace({np.nan: None}).to_dict("records")}
    return sim, choice


def regime_setup(cfg: RobotSettings, urdf, limits, calibration_path=None,
                 servo_ball_path=None) -> tuple[Regime, Robot, BallParams | None]:
    """(the configured regime, the robot of its dynamics, the servo's ball) from a robot rule's inputs: the
    calibration artifact of a calibrated regime and the servo ball's (None: the servo model's default)."""
    calibration = None if calibration_path is None else read_json(calibration_path, REGIME_CALIBRATION)
    regime = cfg.resolve(calibration)
    return regime, regime_robot(urdf, limits, regime.dynamics), read_servo_ball(servo_ball_path)


def read_servo_ball(path) -> BallParams | None:
    """The servo's ball coefficients of a fit_servo_ball artifact (None for no path)."""
    return None if path is None else BallParams(**read_json(path, SERVO_BALL)["params"])
