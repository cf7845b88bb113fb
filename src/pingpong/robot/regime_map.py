"""The regime map: where anticipation and uncertainty pay. Every controller of Tables 2-4 (and perfect
predictions) in each cell: the named regimes of config robot.regime_map.named, and the base regime at
every point of the grid of robot.regime_map.axes (e.g. base acceleration x latency).

In each cell the tuned controllers are swept on the calibration hits (their sweeps are the surfaces:
hits over alpha1 x alpha2, and over the confidence ramp's u_full x u_zero) and every controller runs on
the test hits. The value of anticipation is basic anticipation's hits minus servo's, the value of
uncertainty the best uncertainty-following controller's (confidence-scaled on the configured estimator,
else uncertainty-aware, by calibration hits) minus basic anticipation's, each with a paired bootstrap
interval over the test hits (robot.evaluate.bootstrap_hit_difference).
"""

import numpy as np
import pandas as pd

from pingpong.robot.ablation import PERFECT, perfect_predictions
from pingpong.robot.controllers import CONTROLLERS
from pingpong.robot.evaluate import SimSettings, bootstrap_hit_difference, simulate_hits
from pingpong.robot.model import Robot
from pingpong.robot.sweep import choose_controller

# the controllers of a cell, in order; the tuned ones' sweeps are the surfaces
MAP_CONTROLLERS = ("servo", "anticipatory", "uncertainty_aware", "confidence_scaled",
                   "confidence_scaled_oracle", "perfect")
UNCERTAINTY_CONTROLLERS = ("confidence_scaled", "uncertainty_aware")  # the best of these, by calibration hits


def run_cell(robot: Robot, parts: dict, settings: SimSettings, alphas: list[float],
             quantiles: list[float]) -> dict:
    """Every MAP_CONTROLLERS entry that has its predictions in `parts` (split -> (hits, flights,
    predictions by kind: plain, estimator, oracle)): its choice and sweep on the calibration hits and its
    per-hit test results (hit, end distance)."""
    out = {}
    for name in MAP_CONTROLLERS:
        kind = "perfect" if name == "perfect" else (
            "estimator" if CONTROLLERS[name].uses_uncertainty else
            "oracle" if CONTROLLERS[name].uses_oracle else "plain")
        if kind != "perfect" and parts["test"][2].get(kind) is None:
            continue  # no estimator configured, or not a twin run
        if name == "perfect":
            controller, sweep = PERFECT, None
            test_preds = perfect_predictions(parts["test"][0], parts["test"][2]["plain"])
        else:
            hits, flights, preds = parts["calibration"]
            controller, sweep = choose_controller(name, robot, hits, flights, preds[kind], settings, alphas,
                                                  quantiles)
            test_preds = parts["test"][2][kind]
        sim = simulate_hits(robot, parts["test"][0], parts["test"][1], test_preds, controller, settings)
        out[name] = {"choice": controller.to_choice(),
                     "sweep": [] if sweep is None else sweep.replace({np.nan: None}).to_dict("records"),
                     "region": sim["region"].tolist(), "hit": sim["hit_ball"].astype(bool).tolist(),
                     "end_distance_m": sim["end_distance_m"].replace({np.nan: None}).tolist()}
    return out


def best_uncertainty_controller(results: dict) -> str | None:
    """The uncertainty-following controller with the most calibration hits in its sweep (the first of
    UNCERTAINTY_CONTROLLERS on a tie); None if none ran."""
    best, best_hits = None, -1
    for name in UNCERTAINTY_CONTROLLERS:
        if name in results and results[name]["sweep"]:
            hits = max(row["hits"] for row in results[name]["sweep"])
            if hits > best_hits:
                best, best_hits = name, hits
    return best


def alpha_monotone(sweep: list[dict]) -> bool:
    """Whether the alpha sweep's most hits are at the largest alphas (alpha1 = alpha2 = max): False for an
    interior optimum, where moving early at full speed loses balls."""
    table = pd.DataFrame(sweep)
    top = table[(table["alpha1"] == table["alpha1"].max()) & (table["alpha2"] == table["alpha2"].max())]
    return bool(top["hits"].max() >= table["hits"].max())


def value_row(results: dict, base: str, other: str, rng: np.random.Generator, n_boot: int) -> dict:
    """Hits of `other` minus `base` on the same test hits, with its paired bootstrap 95 % interval."""

    a, b = np.asarray(results[base]["hit"], bool), np.asarray(results[other]["hit"], bool)
    low, high = bootstrap_hit_difference(a, b, rng, n_boot)
    return {"value": int(b.sum() - a.sum()), "ci95_low": low, "ci95_high": high}
