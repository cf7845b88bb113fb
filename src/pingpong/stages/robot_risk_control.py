"""Rule robot_risk_control: anticipation with a guarantee. Every calibration and test hit is simulated under
each gain rule of the configured family; the gain is chosen on the calibration hits by Learn then Test so
that the miss rate exceeds servo's by at most epsilon with probability >= 1 - delta, and checked on the
test hits of the dataset's split and of random re-splits (pingpong.robot.risk_control)."""

import logging

from pingpong.common.artifacts import read_table
from pingpong.curation.schemas import DATASET
from pingpong.learning.schemas import PREDICTIONS
from pingpong.reports.tables import write_report_table
from pingpong.robot.evaluate import RobotSettings, sim_settings
from pingpong.robot.flights import read_ball_tables
from pingpong.robot.risk_control import RiskSettings, check_lambdas, risk_control_report
from pingpong.robot.simulate import final_predictions, regime_setup
from pingpong.uncertainty.schemas import UNCERTAINTY

log = logging.getLogger("robot_risk_control")

CAPTION = """Anticipation with a guarantee (beyond the paper). The early gain alpha (the share of full speed
before the first visual-servoing goal) of each prediction is f_lambda(u) of its calibrated uncertainty u
({estimator}), family '{family}' (step: alpha = 1 where u <= the lambda-quantile of the pooled hits' used
uncertainties, else 0; uniform: alpha = lambda), lambda in {lambdas}. lambda is chosen on the calibration
hits by Learn then Test (Angelopoulos, Bates, Candes, Jordan and Lei 2021; {testing} testing, the '{bound}'
upper bound of the excess miss rate over servo at delta = {delta}) so that the miss rate with anticipation
is at most servo's plus epsilon = {epsilon} with probability >= 1 - delta; lambda = 0 is servo. Rows: the
dataset's split ({n_cal} calibration, {n_test} test hits), {n_resplits} random re-splits of those {n_pool}
hits (as many calibrating), and the summary: the re-splits' mean lambda and miss rates, how often the test
miss rate exceeded servo's plus epsilon (exceeds), its Clopper-Pearson 95 % interval, and the most
exceedances a rate of delta allows (the 95 % quantile of Binomial({n_resplits}, delta); bar_met: no more
than that; the re-splits share hits, so the interval is indicative). calibration_upper_bound_pct: the bound
at the chosen lambda; anticipatory_exceeds: the same check of basic anticipation (alpha = 1). The guarantee
is on the expected miss rate; a test set's rate scatters around it. predictions: model = the final model's;
the stress controls (config robot.risk_control.stress_controls; each prediction keeps its uncertainty),
where anticipation hurts and the guarantee must still hold: mirrored = strike x -> -x (the robot sent the
wrong way), shuffled = each hit given another hit's predictions. Misses over all {n_pool} hits per lambda:
{sweep}. Regime {regime}."""


def main(ctx):
    p, i, o = ctx.params, ctx.input, ctx.output
    cfg, risk = RobotSettings.from_config(p["settings"]), RiskSettings.from_config(p["risk_control"])
    lambdas = check_lambdas(risk.lambdas)
    dataset = read_table(i.dataset, DATASET).drop(columns=["x"])
    uncertainty_path = ctx.optional_input("uncertainty")
    uncertainty = None if uncertainty_path is None else read_table(uncertainty_path, UNCERTAINTY)
    regime, robot, servo_ball = regime_setup(cfg, i.urdf, i.limits, ctx.optional_input("calibration"),
                                             ctx.optional_input("servo_ball"))
    settings = sim_settings(regime, dataset.loc[dataset["split"] == "train", "strike_z"].median(), servo_ball)
    balls = read_ball_tables(p["sessions"], i.balls, i.seen_balls, p["seen_cutoff_hz"])
    predictions = final_predictions(read_table(i.predictions, PREDICTIONS))
    table, sweeps = risk_control_report(robot, dataset, balls, predictions, uncertainty, risk, settings,
                                        cfg.max_flight_s, p["seed"])
    log.info("summary: %s", table[table["kind"] == "summary"].to_dict("records"))
    own = table[(table["kind"] == "dataset split")].iloc[0]
    caption = CAPTION.format(
        estimator=p["estimator"] or "none", family=risk.family, lambdas=[float(x) for x in lambdas],
        testing=risk.testing.replace("_", "-"), bound=risk.bound, delta=risk.delta, epsilon=risk.epsilon,
        n_cal=int(own["n_calibration"]), n_test=int(own["n_test"]), n_resplits=risk.n_resplits,
        n_pool=int(own["n_calibration"] + own["n_test"]), sweep="; ".join(sweeps), regime=cfg.regime_name)
    write_report_table(table, o.md, o.csv, "Risk-controlled anticipation", caption)
