"""Why visual servoing alone misses where it does: the measurements behind the table2 regime's knobs.

Servo alone (the paper's robot and timing, the paper's servo fit) on the hits the calibration fits on
(training and calibration), by region: with a perfect ball; with 5 mm of noise on the seen ball; with the
true strike point given at the first servo goal (t = +10: what reach alone allows, and how fast the balls
it misses are); and with the flights mirrored in x (is the left/right difference the robot's or the
data's?). pingpong.robot.calibration's docstring quotes these figures for the default run of fb04da0.
Run from a finished run's root (default config: causal inputs, no seen-ball low-pass):
`PYTHONPATH=/work/main/src /work/main/.venv/bin/python /work/main/analysis/table2_misses.py`.
"""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from pingpong.common.artifacts import read_table
from pingpong.common.config import schema_defaults
from pingpong.curation.schemas import DATASET
from pingpong.robot.episode import GoalSchedule, run_episode, strike_crossing
from pingpong.robot.evaluate import episode_params
from pingpong.robot.flights import HitFlight, hit_flights, read_ball_tables
from pingpong.robot.model import regime_robot
from pingpong.robot.regimes import parse_regime
from pingpong.robot.simulate import read_servo_ball

REPO = Path(__file__).resolve().parents[1]


def episodes(robot, flights, params, reach_only: bool) -> list[dict]:
    """Per flight: hit, end distance, strike time; reach_only: the goal is the true strike point from the
    first servo goal on (no estimate)."""
    rows = []
    for flight in flights:
        t_strike, ball = strike_crossing(flight.times, flight.positions, params.control.strike_y)
        schedule = None
        if reach_only:
            t0 = params.servo_start_frame * 0.01
            schedule = GoalSchedule(np.array([t0]), ball[[0, 2]][None], t0, 0)
        out = run_episode(robot, flight.times, flight.positions, None, params,
                          seen=(flight.seen_times, flight.seen_positions), schedule=schedule)
        rows.append({"hit": out["hit"], "end_distance_m": out["end_distance_m"], "t_strike_s": t_strike})
    return rows


def main() -> None:
    defaults = schema_defaults(REPO / "config/schema.yaml")
    spec = {**defaults["robot"]["regimes"]["table2"], "calibrated": False, "servo_fit": "paper"}
    dataset = read_table("processed/dataset.parquet", DATASET).drop(columns=["x"])
    hits = dataset[dataset["split"].isin(["train", "calibration"])].reset_index(drop=True)
    sessions = sorted(p.name.removesuffix("_ball.parquet")
                      for p in Path("interim/filtered").glob("*_ball.parquet"))
    judged, seen = read_ball_tables(sessions, [f"interim/filtered/{s}_ball.parquet" for s in sessions],
                                    [f"interim/causal/{s}_ball.parquet" for s in sessions], None)
    flights = hit_flights(hits, judged, defaults["robot"]["max_flight_s"], seen)
    mirror = np.array([-1.0, 1.0, 1.0])
    mirrored = [HitFlight(f.times, f.positions * mirror, f.seen_times, f.seen_positions * mirror)
                for f in flights]
    ball = read_servo_ball("processed/robot/servo_ball.json")
    regime = parse_regime("table2", spec)
    robot = regime_robot(REPO / "config/robot/iiwa14_ridgeback.urdf", REPO / "config/robot/limits.yaml",
                         regime.dynamics)
    perfect = episode_params(regime, ball)
    noisy = replace(perfect, sensing=replace(perfect.sensing, noise_m=0.005))
    cases = {"perfect ball": (flights, perfect, False, hits["region"]),
             "5 mm noise": (flights, noisy, False, hits["region"]),
             "true strike point at t = +10": (flights, perfect, True, hits["region"]),
             "mirrored flights, perfect ball": (mirrored, perfect, False,
                                                hits["region"].map({"left": "right", "right": "left"})
                                                .fillna("centre"))}
    for name, (tracks, params, reach_only, regions) in cases.items():
        table = pd.DataFrame(episodes(robot, tracks, params, reach_only)).assign(region=regions.to_numpy())
        summary = table.groupby("region").agg(n=("hit", "size"), hit_pct=("hit", "mean"),
                                              end_distance_cm=("end_distance_m", "mean"))
        summary[["hit_pct", "end_distance_cm"]] *= 100
        print(f"\n{name} ({len(hits)} training and calibration hits)\n{summary.round(1).to_string()}")
        if reach_only:
            misses = table[~table["hit"]]
            away = 100 * misses["end_distance_m"]
            reached = table.loc[table["hit"], "t_strike_s"].mean()
            print(f"missed: {away.min():.0f}-{away.max():.0f} cm away, strike "
                  f"{misses['t_strike_s'].mean():.2f} s after the hit on average against {reached:.2f} s "
                  "for those reached")


if __name__ == "__main__":
    main()
