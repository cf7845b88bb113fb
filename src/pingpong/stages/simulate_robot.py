"""Rule simulate_robot: one registered controller over the measured test hits, tuned first on the
calibration hits where it has a grid; the chosen settings (and the sweep) go to a JSON artifact beside
the table (pingpong.robot.simulate)."""

import logging

from pingpong.common.artifacts import read_table, write_json, write_table
from pingpong.curation.schemas import DATASET
from pingpong.learning.schemas import PREDICTIONS
from pingpong.robot.evaluate import RobotSettings
from pingpong.robot.flights import read_ball_tables
from pingpong.robot.schemas import CHOICE, SIM
from pingpong.robot.simulate import final_predictions, regime_setup, simulate_controller
from pingpong.uncertainty.schemas import UNCERTAINTY

log = logging.getLogger("simulate_robot")


def main(ctx):
    p, i = ctx.params, ctx.input
    dataset = read_table(i.dataset, DATASET).drop(columns=["x"])
    uncertainty = read_table(i.uncertainty[0], UNCERTAINTY) if i.get("uncertainty") else None
    balls = read_ball_tables(p["sessions"], i.balls, i.seen_balls, p["seen_cutoff_hz"])
    cfg = RobotSettings.from_config(p["settings"])
    regime, robot, servo_ball = regime_setup(cfg, i.urdf, i.limits, ctx.optional_input("calibration"),
                                             ctx.optional_input("servo_ball"))
    sim, choice = simulate_controller(p["controller"], robot, dataset,
                                      final_predictions(read_table(i.predictions, PREDICTIONS)), balls,
                                      uncertainty, cfg, regime, servo_ball)
    log.info("controller %s on %d test hits: %d hits; limits kept in %d", choice["controller"], len(sim),
             sim["hit_ball"].sum(), sim["limits_ok"].sum())
    prov = ctx.provenance()
    write_table(sim, ctx.output.sim, SIM, prov)
    write_json(choice, ctx.output.choice, CHOICE, prov)
