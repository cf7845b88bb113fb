"""Tuning a controller on the calibration hits: every cell of a grid is simulated, the most hits wins.

Ties (few calibration hits make them common) go to the smaller mean end distance, then to the earlier
cell of the grid, so the choice is deterministic.
"""

from itertools import product

import numpy as np
import pandas as pd

from pingpong.robot.evaluate import CONTROLLERS, Controller, Prediction, SimSettings, simulate_hits
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


def alpha_grid(name: str, alphas: list[float]) -> list[Controller]:
    """The paper's uncertainty-aware controller at every (alpha1, alpha2) of the grid."""
    return [Controller(name, float(a1), float(a2), skip_centre=True) for a1, a2 in product(alphas, alphas)]


def confidence_grid(name: str, uncertainty: np.ndarray, quantiles: list[float]) -> list[Controller]:
    """The confidence ramp at every (u_full <= u_zero) pair of quantiles of the calibration uncertainties."""
    finite = np.asarray(uncertainty, float)[np.isfinite(uncertainty)]
    if len(finite) == 0:  # e.g. a conformal factor from too few calibration hits is infinite
        raise ValueError("the confidence-scaled controller needs finite calibration uncertainties; the "
                         "configured estimator (config robot.estimator) gave none: choose another")
    levels = np.quantile(finite, sorted(quantiles))
    return [Controller(name, 1.0, 1.0, confidence=(float(lo), float(hi)))
            for i, lo in enumerate(levels) for hi in levels[i:]]


def choose_controller(name: str, robot: Robot, hits: pd.DataFrame, flights: list,
                      predictions: list[Prediction], settings: SimSettings, alphas: list[float],
                      quantiles: list[float]) -> tuple[Controller, pd.DataFrame | None]:
    """The controller `name` (evaluate.CONTROLLERS), tuned on the given (calibration) hits where it has a
    sweep; returns it and the sweep's table (None for the fixed servo and anticipatory controllers)."""
    if name == "servo":
        return Controller(name), None
    if name == "anticipatory":
        return Controller(name, 1.0, 1.0), None
    if name in ("uncertainty_aware", "confidence_scaled") and len(hits) == 0:
        raise ValueError(f"controller '{name}' is tuned on the calibration hits, and there are none")
    if name == "uncertainty_aware":
        candidates = alpha_grid(name, alphas)
    elif name == "confidence_scaled":
        candidates = confidence_grid(name, np.concatenate([p.uncertainty for p in predictions]), quantiles)
    else:
        raise ValueError(f"unknown controller '{name}'; expected one of {CONTROLLERS}")
    return sweep(robot, hits, flights, predictions, candidates, settings)
