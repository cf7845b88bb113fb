"""Rule regime_cell: one cell of the regime map, every controller of Tables 2-4 and perfect predictions
tuned on the calibration hits and run on the test hits under the cell's regime
(pingpong.robot.regime_map)."""

import logging

from pingpong.common.artifacts import read_json, read_table, write_json
from pingpong.curation.schemas import DATASET
from pingpong.learning.schemas import PREDICTIONS
from pingpong.robot.evaluate import hit_predictions, sim_settings
from pingpong.robot.flights import hit_flights, read_ball_tables
from pingpong.robot.model import regime_robot
from pingpong.robot.regime_map import run_cell
from pingpong.robot.regimes import parse_regime
from pingpong.robot.schemas import REGIME_CALIBRATION, REGIME_CELL
from pingpong.robot.simulate import final_predictions, read_servo_ball
from pingpong.uncertainty.schemas import UNCERTAINTY

log = logging.getLogger("regime_cell")


def main(ctx):
    p, i = ctx.params, ctx.input
    dataset = read_table(i.dataset, DATASET).drop(columns=["x"])
    predictions = final_predictions(read_table(i.predictions, PREDICTIONS))
    tables = {"estimator": ctx.optional_input("uncertainty"), "oracle": ctx.optional_input("oracle")}
    tables = {k: None if v is None else read_table(v, UNCERTAINTY) for k, v in tables.items()}
    judged, seen = read_ball_tables(p["sessions"], i.balls, i.seen_balls, p["seen_cutoff_hz"])
    parts = {}
    for split in ("calibration", "test"):
        hits = dataset[dataset["split"] == split].reset_index(drop=True)
        preds = {"plain": hit_predictions(predictions, hits)}
        preds |= {k: None if t is None else hit_predictions(predictions, hits, t) for k, t in tables.items()}
        parts[split] = (hits, hit_flights(hits, judged, p["max_flight_s"], seen), preds)
    calibration = ctx.optional_input("calibration")
    regime = parse_regime(p["cell"], p["spec"], p["seed"],
                          None if calibration is None else read_json(calibration, REGIME_CALIBRATION))
    robot = regime_robot(i.urdf, i.limits, regime.dynamics)
    settings = sim_settings(regime, dataset.loc[dataset["split"] == "train", "strike_z"].median(),
                            read_servo_ball(i.servo_ball))
    results = run_cell(robot, parts, settings, p["alpha_grid"], p["confidence_quantiles"])
    log.info("cell %s on %d test hits: %s", p["cell"], len(parts["test"][0]),
             {name: sum(r["hit"]) for name, r in results.items()})
    write_json({"cell": p["cell"], "description": p["spec"].get("description", ""),
                "grid_point": p["spec"].get("grid_point", {}), "sensing": regime.sensing.__dict__,
                "servo_fit": regime.servo_fit, "dynamics": regime.dynamics.__dict__,
                "n_calibration_hits": len(parts["calibration"][0]),
                "controllers": results},
               ctx.output.cell, REGIME_CELL, ctx.provenance())
