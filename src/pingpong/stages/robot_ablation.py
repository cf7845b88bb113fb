"""Rule robot_ablation: servo-only and anticipatory hits on the test hits under every combination of the
paper's and the project's accelerations, timing and inputs, the other servo fit, and perfect predictions
(pingpong.robot.ablation); and each servo fit's strike estimate error on the test flights
(pingpong.reports.servo_accuracy)."""

import logging
from dataclasses import replace

import pandas as pd

from pingpong.common.artifacts import read_table
from pingpong.curation.schemas import DATASET
from pingpong.frames import STRIKE_Y
from pingpong.learning.schemas import PREDICTIONS
from pingpong.reports.servo_accuracy import servo_accuracy
from pingpong.reports.tables import write_report_table
from pingpong.robot.ablation import AXES, flight_timing, run_ablation, timing_name
from pingpong.robot.evaluate import RobotSettings, hit_predictions
from pingpong.robot.flights import hit_flights, read_ball_tables
from pingpong.robot.model import regime_robot
from pingpong.robot.regimes import Timing
from pingpong.robot.servo_ball import (
    REAL_FRAMES_AFTER_LAUNCH,
    describe_ball,
    real_flight_in_table_frame,
    servo_fits,
    split_flights,
)
from pingpong.robot.simulate import regime_setup
from pingpong.twin.realdata import load_real_flights

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
seen (pingpong.robot.servo) with the servo's own ball ({ball}: drag and bounce fitted on half the real MPI
ball-gun flights, the lift Stepanek's 1988 C_L = 1 / (2 + 1/S); pingpong.robot.servo_ball, rule
fit_servo_ball); model_twin_ball: the same fit with the twin's ball coefficients (which flatter it on the
twin's flights). flights ball_gun: the other {n_real} real flights (held out from the ball's fit; MPI
Tuebingen, BSD 3-Clause, data/realdata/mpi_ball_gun), each placed in the table frame with its bounce on
the table and the strike line 60 % of its post-bounce track past the bounce; frames count from the launch
there (10 ms), the bounce comes at ~0.6 s."""


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
    regime, _, servo_ball = regime_setup(cfg, i.urdf, i.limits, ctx.optional_input("calibration"),
                                         ctx.optional_input("servo_ball"))
    robots = {name: regime_robot(i.urdf, i.limits, replace(regime.dynamics, arm_accelerations=name))
              for name in AXES["accelerations"]}
    timings = {name: Timing(**timing) for name, timing in p["timings"].items()}
    anticipation_z = dataset.loc[dataset["split"] == "train", "strike_z"].median()
    table = run_ablation(robots, test, flights, by_inputs, regime, timings, p["inputs"], anticipation_z,
                         servo_ball)
    log.info("%d cells x controllers on %d test hits", len(table), len(test))
    timing = flight_timing(flights[p["inputs"]], STRIKE_Y)
    timing_text = "; ".join(f"{r.quantity} {r.median:.3g} {r.unit} (p10 {r.p10:.3g}, p90 {r.p90:.3g})"
                            for r in timing.itertuples())
    timing_used = timing_name(regime, timings)
    configured = (f"accelerations {regime.dynamics.arm_accelerations}, timing {timing_used}, "
                  f"inputs {p['inputs']}, servo_fit {regime.servo_fit}")
    write_report_table(table, ctx.output.md, ctx.output.csv, "Robot ablation",
                       CAPTION.format(n=len(test), configured=configured, timing=timing_text))
    seen = [(f.seen_times, f.seen_positions) for f in flights[p["inputs"]]]
    fits = servo_fits(servo_ball)
    _, held_out = split_flights(load_real_flights(i.real))
    real = [real_flight_in_table_frame(f) for f in held_out]
    servo = pd.concat([
        servo_accuracy(seen, fits, strike_y=STRIKE_Y).assign(flights="test"),
        servo_accuracy(real, fits, REAL_FRAMES_AFTER_LAUNCH, STRIKE_Y).assign(flights="ball_gun")])
    servo = servo[["flights", *servo.columns[:-1]]]
    caption = SERVO_CAPTION.format(n=len(test), inputs=p["inputs"], n_real=len(real),
                                   ball=describe_ball(servo_ball))
    write_report_table(servo, ctx.output.servo_md, ctx.output.servo_csv, "Servo strike estimates", caption)
