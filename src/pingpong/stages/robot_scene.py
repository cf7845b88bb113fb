"""Rule robot_scene: the first test hits' episodes under every controller, re-run as simulate_robot ran them,
as Foxglove MCAP scenes, and the simulation figure (each episode at the strike)."""

import json
import logging
from dataclasses import asdict
from pathlib import Path

from pingpong.common.artifacts import read_json, read_table
from pingpong.curation.schemas import DATASET
from pingpong.learning.schemas import PREDICTIONS
from pingpong.robot.evaluate import RobotSettings
from pingpong.robot.flights import read_ball_tables
from pingpong.robot.scene import (
    check_against_sim,
    controller_scenes,
    prediction_labels,
    robot_visuals,
    scene_hits,
    write_scene_mcap,
)
from pingpong.robot.scene_figure import plot_scenes
from pingpong.robot.schemas import CHOICE, SIM
from pingpong.robot.simulate import final_predictions, hit_parts, regime_setup
from pingpong.uncertainty.schemas import UNCERTAINTY

log = logging.getLogger("robot_scene")


def main(ctx):
    p, cfg, i = ctx.params, RobotSettings.from_config(ctx.params["settings"]), ctx.input
    hits = scene_hits(read_table(i.dataset, DATASET), p["n_hits"])
    predictions = final_predictions(read_table(i.predictions, PREDICTIONS))
    uncertainty = read_table(i.uncertainty[0], UNCERTAINTY) if i.get("uncertainty") else None
    balls = read_ball_tables(p["sessions"], i.balls, i.seen_balls, p["seen_cutoff_hz"])
    labels = prediction_labels(predictions, hits)
    regime, robot, servo_ball = regime_setup(cfg, i.urdf, i.limits, ctx.optional_input("calibration"),
                                             ctx.optional_input("servo_ball"))
    visuals = robot_visuals(robot)
    outputs = {Path(path).name: path for path in ctx.output.mcaps}
    # the same provenance as the Parquet artifacts', as the MCAP metadata record 'pingpong'
    provenance = {"pingpong": {k: v if isinstance(v, str) else json.dumps(v)
                               for k, v in asdict(ctx.provenance()).items()}}
    camera_ns = {s: ball["time_ns"].to_numpy() for s, ball in balls[0].items()}
    scenes = []
    for name, sim_path, choice_path in zip(p["controllers"], i.sims, i.choices, strict=True):
        _, flights, hit_preds = hit_parts(hits, balls, predictions, uncertainty, name, cfg.max_flight_s)
        episodes = controller_scenes(robot, hits, camera_ns, flights, hit_preds, labels,
                                     read_json(choice_path, CHOICE), regime, servo_ball)
        sim = read_table(sim_path, SIM)
        for k, scene in enumerate(episodes):
            check_against_sim(scene, sim, sim_path)
            write_scene_mcap(outputs[f"{name}_test{k}.mcap"], scene, robot, visuals, provenance)
            info = scene.info
            log.info("%s test hit %d (%s rally %d hit %d): %s, %.3f m, %d frames", name, k, info["session"],
                     info["rally"], info["hit"], "hit" if info["hit_ball"] else "miss",
                     info["end_distance_m"], len(scene.times))
        scenes += episodes
    order = {(h.session, h.rally, h.hit): k for k, h in enumerate(hits.itertuples(index=False))}
    scenes.sort(key=lambda s: order[s.info["session"], s.info["rally"], s.info["hit"]])  # stable: controllers
    plot_scenes(scenes, robot, visuals, ctx.output.figure)
