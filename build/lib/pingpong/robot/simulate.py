"""One controller over a run's hits: tuned on the calibration hits where it has a grid, then simulated on
the test hits (the simulate_robot rule); and what robot_scene re-runs of it."""

import numpy as np
import pandas as pd

from pingpong.robot.controllers import CONTROLLERS
from pingpong.robot.evaluate import RobotSettings, hit_predictions, sim_settings, simulate_hits
from pingpong.robot.flights import hit_flights
from pingpong.robot.model import Robot
from pingpong.robot.sweep import choose_controller


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
                        cfg: RobotSettings) -> tuple[pd.DataFrame, dict]:
    """(SIM table of the test hits, the CHOICE record: the chosen settings and the calibration sweep).

    dataset: DATASET rows; predictions: the final model's; balls: (judged, seen) session -> ball table
    (flights.hit_flights); uncertainty: the configured estimator's table (None: no estimator).
    """
    settings = sim_settings(cfg, dataset.loc[dataset["split"] == "train", "strike_z"].median())
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
