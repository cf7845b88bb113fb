"""Why the robot hits what it hits: servo-only and anticipatory hits on the test hits under each change
from the paper's setting alone and together, and with perfect predictions (reports/tables/robot_ablation).

Axes (every combination is simulated), each around the configured regime (regimes.py):
  - accelerations: the arm's, the paper's Table 6 / Drake's (config/robot/limits.yaml);
  - timing: that of the regime paper (10 Hz goals, 0.1 s steps) / of the regime fine (10 ms steps, 100 ms
    latency on top) (config robot.regimes);
  - inputs: causal / zero-phase, for the model the anticipatory controller follows and the ball the servo
    sees (curation.dataset, flights.py).
Beside them, at the configured setting: the paper's servo fit instead of the configured one, and the
'perfect' controller, anticipating on the label's strike x at every frame (the ceiling of anticipation
with the model's goal height; the servo then corrects the height as for every controller).
"""

from dataclasses import replace
from itertools import product

import numpy as np
import pandas as pd

from pingpong.robot.controllers import CONTROLLERS, Controller
from pingpong.robot.episode import strike_crossing
from pingpong.robot.evaluate import Prediction, SimSettings, episode_params, simulate_hits
from pingpong.robot.flights import HitFlight
from pingpong.robot.model import Robot
from pingpong.robot.regimes import Regime, Timing
from pingpong.twin.ball import BallParams

AXES = {"accelerations": ("table6", "drake"), "timing": ("paper", "fine"), "inputs": ("causal", "zero_phase")}
PERFECT = Controller("perfect", 1.0, 1.0)


def perfect_predictions(hits: pd.DataFrame, like: list[Prediction]) -> list[Prediction]:
    """The label's strike x at the frames of each hit's model predictions."""
    return [Prediction(p.frames, np.full(len(p.frames), x))
            for p, x in zip(like, hits["strike_x"], strict=True)]


def timing_name(regime: Regime, timings: dict[str, Timing]) -> str:
    """The name of the regime's timing: that of the first regime in `timings` with the same, else its own."""
    return next((name for name, timing in timings.items() if timing == regime.timing), regime.name)


def configured_cell(regime: Regime, timings: dict[str, Timing], inputs: str) -> dict:
    """The configured setting along every axis and the servo fit."""
    return {"accelerations": regime.dynamics.arm_accelerations, "timing": timing_name(regime, timings),
            "inputs": inputs, "servo_fit": regime.servo_fit}


def cells(regime: Regime, timings: dict[str, Timing], inputs: str) -> list[dict]:
    """The simulated settings: every combination of AXES, then the configured one with the other servo fit
    (servo only) and with perfect predictions; each dict has the axes, servo_fit and the controllers."""
    base = configured_cell(regime, timings, inputs)
    out = [{**base, **dict(zip(AXES, values, strict=True)), "controllers": ("servo", "anticipatory")}
           for values in product(*AXES.values())]
    other_fit = {"model": "paper", "paper": "model"}[regime.servo_fit]
    out.append({**base, "servo_fit": other_fit, "controllers": ("servo",)})
    out.append({**base, "controllers": ("perfect",)})
    return out


def run_ablation(robots: dict[str, Robot], hits: pd.DataFrame, flights: dict[str, list[HitFlight]],
                 predictions: dict[str, list[Prediction]], regime: Regime, timings: dict[str, Timing],
                 inputs: str, anticipation_z: float, servo_ball: BallParams | None = None) -> pd.DataFrame:
    """One row per (cell, controller): hits, total, hit %, mean end distance (cm), limit breaches and servo
    updates without an estimate. robots: by arm acceleration set (the regime's base); flights, predictions:
    by inputs' kind; timings: by name, the timing axis's and the configured regime's."""
    timings = {**timings, regime.name: regime.timing}
    rows, base = [], configured_cell(regime, timings, inputs)
    for cell in cells(regime, timings, inputs):
        cell_regime = replace(regime, timing=timings[cell["timing"]], servo_fit=cell["servo_fit"])
        sim = SimSettings(episode_params(cell_regime, servo_ball), anticipation_z)
        for name in cell["controllers"]:
            controller = PERFECT if name == "perfect" else CONTROLLERS[name].fixed
            preds = (perfect_predictions(hits, predictions[cell["inputs"]]) if name == "perfect"
                     else predictions[cell["inputs"]])
            robot, hit_flights = robots[cell["accelerations"]], flights[cell["inputs"]]
            out = simulate_hits(robot, hits, hit_flights, preds, controller, sim)
            changed = [axis for axis in base if cell[axis] != base[axis]]
            rows.append({**{k: cell[k] for k in base}, "controller": name,
                         "changed": ", ".join(changed) or "none", "total": len(out),
                         "hits": int(out["hit_ball"].sum()), "hit_pct": 100 * out["hit_ball"].mean(),
                         "end_distance_mean_cm": 100 * out["end_distance_m"].mean(),
                         "limit_breaches": int((~out["limits_ok"]).sum()),
                         "servo_no_estimate": int(out["servo_no_estimate"].sum())})
    return pd.DataFrame(rows)


def flight_timing(flights: list[HitFlight], strike_y: float) -> pd.DataFrame:
    """The flights' time from the hit to the strike line and speed just after the hit (10th, 50th, 90th
    percentile): how long the robot has once the first servo goal is usable."""
    t_strike = np.array([strike_crossing(f.times, f.positions, strike_y)[0] for f in flights])
    speed = np.array([np.linalg.norm(f.positions[min(3, len(f.positions) - 1)] - f.positions[0])
                      / max(f.times[min(3, len(f.times) - 1)] - f.times[0], 1e-9) for f in flights])
    rows = []
    for name, values, unit in (("time_to_strike_line", t_strike, "s"), ("speed_after_hit", speed, "m/s")):
        finite = values[np.isfinite(values)]
        rows.append({"quantity": name, "unit": unit, "n": len(finite),
                     **dict(zip(("p10", "median", "p90"), np.percentile(finite, [10, 50, 90]), strict=True))})
    return pd.DataFrame(rows)
