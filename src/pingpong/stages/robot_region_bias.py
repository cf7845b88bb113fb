"""Rule robot_region_bias: the paper's left-region effect on the test hits: per region, the signed strike
bias of the predictions the robot moves on and the end distance with and without anticipation, with
bootstrap intervals, and whether the effect shows (pingpong.robot.region_bias)."""

from pingpong.common.artifacts import read_json, read_table
from pingpong.common.seeding import rng_for
from pingpong.learning.schemas import PREDICTIONS
from pingpong.reports.tables import write_report_table
from pingpong.robot.evaluate import RobotSettings, episode_params
from pingpong.robot.region_bias import effect_shows, region_bias_table
from pingpong.robot.schemas import REGIME_CALIBRATION, SIM
from pingpong.robot.simulate import final_predictions
from pingpong.uncertainty.schemas import UNCERTAINTY

CAPTION = """The paper's left-region effect (its Results after Tables 2-4: on left balls the basic
anticipatory controller ends farther from the ball than visual servoing, 12.82 -> 13.63 cm, because the
model, when unsure, predicts a strike point of positive x towards the centre-right and the robot builds
momentum the wrong way) on the {n} test hits, by region of the true strike point (left x < -0.25 m <=
centre <= 0.25 m < right, as Table 2). strike_bias: predicted minus true strike x at each prediction frame
the robot moves on (frame: from the hit; regime {regime}); wrong_side: % of hits predicted at x of the
other sign than the truth; end_distance_*: paddle centre to ball at the strike line, servo (alpha = 0) and
basic anticipation (alpha = 1) from processed/sim/, and their paired difference (anticipation minus
servo); hits_*: balls hit; with an estimator ({estimator}), the hits of each used frame split at its
median uncertainty: predicted_x_unsure/sure, the mean predicted strike x of each half, and
strike_bias_unsure/sure per region. Means with percentile 95 % intervals over {n_boot} resamples of the hits.
paper_value: the paper's Tables 2 and 3 (mean end distance, cm). paper_effect rows: each part of the
paper's claim shows (1) when its interval excludes no effect, and the row 'all three' says whether all of
them do; the rows after it stand beside them: a lean to the right over all balls (the paper's explanation;
a model that pulls towards the middle leans left balls right without it) and, with an estimator, unsure
predictions right of the middle (the paper's "when uncertain ... towards the center-right").
The effect {verdict}."""


def main(ctx):
    p, i, o = ctx.params, ctx.input, ctx.output
    cfg = RobotSettings.from_config(p["settings"])
    calibration = ctx.optional_input("calibration")
    regime = cfg.resolve(None if calibration is None else read_json(calibration, REGIME_CALIBRATION))
    predictions = final_predictions(read_table(i.predictions, PREDICTIONS))
    predictions = predictions[predictions["split"] == "test"]
    servo, anticipatory = read_table(i.servo, SIM), read_table(i.anticipatory, SIM)
    uncertainty_path = ctx.optional_input("uncertainty")
    uncertainty = None if uncertainty_path is None else read_table(uncertainty_path, UNCERTAINTY)
    table = region_bias_table(predictions, servo, anticipatory, episode_params(regime),
                              rng_for(p["seed"], "robot_region_bias"), p["n_bootstrap"], uncertainty)
    verdict = "shows here" if effect_shows(table) else "does not show here (see the paper_effect rows)"
    caption = CAPTION.format(n=len(servo), regime=cfg.regime_name, n_boot=p["n_bootstrap"], verdict=verdict,
                             estimator=p["estimator"] or "none configured")
    write_report_table(table, o.md, o.csv, "The paper's left-region effect", caption)
