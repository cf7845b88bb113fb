"""Rule calibrate_regime: the sensing, servo and reach knobs of a calibrated regime, fitted on the hits of
config robot.calibration.splits so that visual servoing alone reproduces the paper's Table 2
(pingpong.robot.calibration).

Visual servoing alone reads no learned prediction, so fitting on the training hits as well as the
calibration hits (the default, ~8x as many) leaks nothing into the learned models' evaluation; the test
hits, on which the regime is reported, are never fitted on."""

import logging

import numpy as np

from pingpong.common.artifacts import read_table, write_json
from pingpong.curation.schemas import DATASET
from pingpong.robot.calibration import DYNAMICS_KNOBS, PAPER_TABLE2, SENSING_KNOBS, calibrate, region_stats
from pingpong.robot.controllers import CONTROLLERS
from pingpong.robot.evaluate import Prediction, SimSettings, sim_settings, simulate_hits
from pingpong.robot.flights import hit_flights, read_ball_tables
from pingpong.robot.model import regime_robot
from pingpong.robot.regimes import parse_regime
from pingpong.robot.schemas import REGIME_CALIBRATION
from pingpong.robot.simulate import read_servo_ball

log = logging.getLogger("calibrate_regime")
TARGET_FIELDS = ("hits", "total", "end_distance_mean_cm", "half_std_cm")


def main(ctx):
    p, i = ctx.params, ctx.input
    dataset = read_table(i.dataset, DATASET).drop(columns=["x"])
    hits = dataset[dataset["split"].isin(p["grid"]["splits"])].reset_index(drop=True)
    judged, seen = read_ball_tables(p["sessions"], i.balls, i.seen_balls, p["seen_cutoff_hz"])
    flights = hit_flights(hits, judged, p["max_flight_s"], seen)
    none = [Prediction(np.zeros(0, int), np.zeros(0)) for _ in range(len(hits))]  # servo follows none
    servo_ball = read_servo_ball(i.servo_ball)
    anticipation_z = dataset.loc[dataset["split"] == "train", "strike_z"].median()
    spec = {**p["spec"], "calibrated": False}
    robots, settings = {}, {}  # by dynamics knobs, and by sensing and servo fit: the servo's goals are
    # the same whatever the robot, so one SimSettings (its schedule cache) serves every dynamics point

    def simulate(knobs):
        sensing = {k: knobs.get(k, spec["sensing"].get(k, 0)) for k in SENSING_KNOBS}
        dynamics = {**spec["dynamics"], **{k: knobs[k] for k in DYNAMICS_KNOBS if k in knobs}}
        fit = knobs.get("servo_fit", spec["servo_fit"])
        regime = parse_regime(p["regime"], {**spec, "sensing": sensing, "servo_fit": fit,
                                            "dynamics": dynamics}, p["seed"])
        robot_key, sensing_key = tuple(sorted(dynamics.items())), (tuple(sorted(sensing.items())), fit)
        if robot_key not in robots:
            robots[robot_key] = regime_robot(i.urdf, i.limits, regime.dynamics)
        if sensing_key not in settings:
            settings[sensing_key] = sim_settings(regime, anticipation_z, servo_ball)
        cached: SimSettings = settings[sensing_key]
        return simulate_hits(robots[robot_key], hits, flights, none, CONTROLLERS["servo"].fixed, cached)

    knobs, table = calibrate(simulate, p["grid"])
    stats = region_stats(simulate(knobs))
    log.info("regime %s calibrated on %d %s hits: %s (misfit %.2f)", p["regime"], len(hits),
             p["grid"]["splits"], knobs, table["misfit"].min())
    write_json({"regime": p["regime"], "n_calibration_hits": len(hits), "splits": p["grid"]["splits"],
                "sensing": {k: knobs.get(k, spec["sensing"].get(k, 0)) for k in SENSING_KNOBS},
                "servo_fit": knobs.get("servo_fit", spec["servo_fit"]),
                "dynamics": {k: knobs[k] for k in DYNAMICS_KNOBS if k in knobs},
                "target": {"source": "Rahmanian et al. 2023, Table 2 (visual servoing alone)",
                           "regions": {r: dict(zip(TARGET_FIELDS, v, strict=True))
                                       for r, v in PAPER_TABLE2.items()}},
                "calibration_stats": stats.to_dict("records"),
                "grid": table.replace({np.nan: None}).to_dict("records")},
               ctx.output.calibration, REGIME_CALIBRATION, ctx.provenance())
