"""Tuning a controller on the calibration hits: every cell of a grid is simulated, the most hits wins.

Ties (few calibration hits make them common) go to the smaller mean end distance, then to the earlier
cell of the grid, so the choice is deterministic.
"""

import numpy as np
import pandas as pd

from pingpong.robot.controllers import CONTROLLERS, Controller, Tuning
from pingpong.robot.evaluate import Prediction, SimSettings, simulate_hits
from pingpong.robot.model import Robot


def best_cell(results: pd.DataFrame) -> int:
    """Row index of the cell with the most hits, then the smallest mean end distance, then the first."""
    distance = results["mean_end_distance_m"].fillna(np.inf)
    order = np.lexsort((np.arange(len(results)), distance.to_numpy(), -results["hits"].to_numpy()))
    return int(order[0])


def sweep(robot: Robot, hits: pd.DataFrame, flights: list, predictions: list[Prediction],
          controllers: list[Controller], settings: SimSettings) -> tuple[Controller, pd.DataFrame]:
    """(the best controller, one row per candidate: alpha1, alpha2, u_full, u_zero, hits, mean end
    distance)."""
    rows = []
    for controller in controllers:
        sim = simulate_hits(robot, hits, flights, predictions, controller, settings)
        u_full, u_zero = controller.confidence or (np.nan, np.nan)
        rows.append({"alpha1": controller.alpha1, "alpha2": controller.alpha2, "u_full": u_full,
                     "u_zero": u_zero, "hits": int(sim["hit_ball"].sum()),
                     "mean_end_distance_m": float(sim["end_distance_m"].mean())})
    results = pd.DataFrame(rows)
    return controllers[best_cell(results)], results


def choose_controller(name: str, robot: Robot, hits: pd.DataFrame, flights: list,
                      predictions: list[Prediction], settings: SimSettings, alphas: list[float],
                      quantiles: list[float]) -> tuple[Controller, pd.DataFrame | None]:
    """The registered controller `name`, tuned on the given (calibration) hits where it has a grid;
    returns it and the sweep's table (None for a fixed controller)."""
    if name not in CONTROLLERS:
        raise ValueError(f"unknown controller '{name}'; expected one of {list(CONTROLLERS)}")
    kind = CONTROLLERS[name]
    if kind.fixed is not None:
        return kind.fixed, None
    if len(hits) == 0:
        raise ValueError(f"controller '{name}' is tuned on the calibration hits, and there are none")
    uncertainty = np.concatenate([p.uncertainty for p in predictions]) if kind.follows_uncertainty else None
    return sweep(robot, hits, flights, predictions, kind.grid(name, Tuning(alphas, quantiles, uncertainty)),
                 settings)
