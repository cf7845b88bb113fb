"""Rule robot_ablation: servo-only and anticipatory hits on the test hits under every combination of the
paper's and the project's accelerations, timing and inputs, the other servo fit, and perfect predictions
(pingpong.robot.ablation); and each servo fit's strike estimate error on the test flights
(pingpong.reports.servo_accuracy)."""

import logging

from pingpong.common.artifacts import read_table
from pingpong.curation.schemas import DATASET
from pingpong.frames import STRIKE_Y
from pingpong.learning.schemas import PREDICTIONS
from pingpong.reports.servo_accuracy import servo_accuracy
from pingpong.reports.tables import write_report_table
from pingpong.robot.ablation import AXES, flight_timing, run_ablation
from pingpong.robot.evaluate import RobotSettings, hit_predictions
from pingpong.robot.flights import hit_flights, read_ball_tables
from pingpong.robot.model import load_robot

log = logging.getLogger("robot_ablation")

CAPTION = """Balls hit on the {n} test hits (the same hits, flights and hit test as reports/tables/robot.md)
with visual servoing alone and with the basic anticipatory controller (alpha1 = alpha2 = 1), under every
combination of: accelerations (table6: the paper's Table 6; drake: Drake's, 7-635x lower), timing (paper:
goals at 10 Hz, 0.1 s steps that model the 100 ms latency, servo from t = +10, the predictions of t = -10
and t = 0; fine: 10 ms steps with 100 ms latency on top, a goal every frame) and inputs (causal: the model
and the servo see measurements up to each frame only; zero_phase: the zero-phase filtered ones, as the
paper). Then, at the configured setting, the other servo fit (servo only) and `perfect`: anticipation on
the label's strike x at every frame. `changed`: the axes that differ from the configured setting
({configured}). servo_no_estimate: servo updates whose fit gave no estimate (the robot kept its goal).
The flights: {timing}."""

SERVO_CAPTION = """Visual servoing's strike estimate (the point x, z where the ball crosses y = -1.40 m)
from the ball seen up to 10, 15 and 20 frames after the hit, on the {n} test flights as the servo sees
them ({inputs} inputs; a flight that has crossed by then is left out), against the crossing of that
track: median and 90th percentile of the error (cm) and the share of flights with no estimate (the
fit's stated status; counts per status beside). paper: two quadratics in time with an elastic bounce
(the paper's); model: the project's drag-, Magnus- and bounce-aware ball model fitted to the points
seen (pingpong.robot.servo)."""


def main(ctx):
    p, i = ctx.params, ctx.input
    cfg = RobotSettings.from_config(p["settings"])
    dataset = read_table(i.dataset, DATASET).drop(columns=["x"])
    test = dataset[dataset["split"] == "test"].reset_index(drop=True)
    predictions = read_table(i.predictions, PREDICTIONS)
    models = {p["inputs"]: "final", p["other_inputs"]: p["other_final"]}
    by_inputs = {kind: hit_predictions(predictions[predictions["model"] == model], test)
                 for kind, model in models.items()}
    judged, seen = read_ball_tables(p["sessions"], i.balls, i.causal_balls, p["seen_cutoff_hz"])
    flights = {"causal": hit_flights(test, judged, cfg.max_flight_s, seen),
               "zero_phase": hit_flights(test, judged, cfg.max_flight_s)}
    robots = {name: load_robot(i.urdf, i.limits, name) for name in AXES["accelerations"]}
    anticipation_z = dataset.loc[dataset["split"] == "train", "strike_z"].median()
    table = run_ablation(robots, test, flights, by_inputs, cfg, p["inputs"], anticipation_z)
    log.info("%d cells x controllers on %d test hits", len(table), len(test))
    timing = flight_timing(flights[p["inputs"]], STRIKE_Y)
    timing_text = "; ".join(f"{r.quantity} {r.median:.3g} {r.unit} (p10 {r.p10:.3g}, p90 {r.p90:.3g})"
                            for r in timing.itertuples())
    configured = (f"accelerations {cfg.accelerations}, timing {cfg.timing}, inputs {p['inputs']}, "
                  f"servo_fit {cfg.servo_fit}")
    write_report_table(table, ctx.output.md, ctx.output.csv, "Robot ablation",
                       CAPTION.format(n=len(test), configured=configured, timing=timing_text))
    seen = [(f.seen_times, f.seen_positions) for f in flights[p["inputs"]]]
    write_report_table(servo_accuracy(seen, strike_y=STRIKE_Y), ctx.output.servo_md, ctx.output.servo_csv,
                       "Servo strike estimates", SERVO_CAPTION.format(n=len(test), inputs=p["inputs"]))
