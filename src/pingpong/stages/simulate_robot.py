"""Rule simulate_robot: one controller over the measured test hits, tuned first on the calibration hits
where it has a sweep; the chosen settings (and the sweep) go to a JSON artifact beside the table."""

import logging

import numpy as np

from pingpong.common.artifacts import read_table, write_json, write_table
from pingpong.curation.dataset import DATASET
from pingpong.learning.cv import PREDICTIONS
from pingpong.perception.triangulation import BALL3D
from pingpong.robot.evaluate import CHOICE, SIM, hit_predictions, sim_settings, simulate_hits
from pingpong.robot.flights import hit_flights
from pingpong.robot.model import load_robot
from pingpong.robot.sweep import choose_controller
from pingpong.uncertainty.tables import UNCERTAINTY

log = logging.getLogger("simulate_robot")


def main(ctx):
    p, cfg, i = ctx.params, ctx.params["settings"], ctx.input
    dataset = read_table(i.dataset, DATASET).drop(columns=["x"])
    predictions = read_table(i.predictions, PREDICTIONS)
    predictions = predictions[predictions["model"] == "final"]
    uncertainty = read_table(i.uncertainty[0], UNCERTAINTY) if i.get("uncertainty") else None
    balls = {s: read_table(f, BALL3D, columns=["time_ns", "x", "y", "z"])
             for s, f in zip(p["sessions"], i.balls, strict=True)}
    settings = sim_settings(cfg, dataset.loc[dataset["split"] == "train", "strike_z"].median())
    robot = load_robot(ctx.input.urdf, ctx.input.limits)
    parts = {}
    for split in ("calibration", "test"):
        hits = dataset[dataset["split"] == split].reset_index(drop=True)
        parts[split] = (hits, hit_flights(hits, balls, cfg["max_flight_s"]),
                        hit_predictions(predictions, hits, uncertainty))
    controller, sweep = choose_controller(p["controller"], robot, *parts["calibration"], settings,
                                          cfg["alpha_grid"], cfg["confidence_quantiles"])
    log.info("controller %s on %d test hits", controller, len(parts["test"][0]))
    sim = simulate_hits(robot, *parts["test"], controller, settings)
    log.info("%d hits of %d; limits kept in %d", sim["hit_ball"].sum(), len(sim), sim["limits_ok"].sum())
    prov = ctx.provenance()
    write_table(sim, ctx.output.sim, SIM, prov)
    choice = {"controller": controller.name, "alpha1": controller.alpha1, "alpha2": controller.alpha2,
              "skip_centre": controller.skip_centre, "confidence_m": controller.confidence,
              "anticipation_z_m": settings.anticipation_z, "n_calibration_hits": len(parts["calibration"][0]),
              "sweep": [] if sweep is None else sweep.replace({np.nan: None}).to_dict("records")}
    write_json(choice, ctx.output.choice, CHOICE, prov)
