"""Rule report_regime_map: the regime map's table and heatmap, the surfaces of the named regimes, and the
calibrated regimes against the paper's Table 2 on the test hits (pingpong.reports.robot_regimes)."""

from pingpong.common.artifacts import read_json
from pingpong.common.seeding import rng_for
from pingpong.reports.robot_regimes import calibration_table, regime_map_figure, regime_table, surface_figure
from pingpong.reports.tables import write_report_table
from pingpong.robot.schemas import REGIME_CALIBRATION, REGIME_CELL

CAPTION = """Where anticipation and uncertainty pay: every controller of Tables 2-4 and perfect predictions
(anticipation on the label's strike x) in each regime (config robot.regimes; the named ones {named}, then
the regime {base} over the grid {axes}). Each cell tunes its controllers on the {n_cal} calibration hits
and runs them on the {n_test} test hits (the same hits in every cell): hits_* per controller.
anticipation_value: basic anticipation's balls hit minus visual servoing's; uncertainty_value: the
best uncertainty-following controller's (uncertainty_controller: confidence-scaled on the configured
estimator, or uncertainty-aware, whichever hits more calibration balls) minus basic anticipation's; each
with the paired bootstrap 95 % interval over the test hits ({n_boot} resamples). ua_*: the
uncertainty-aware controller's chosen alphas and its calibration hits at the best cell and at
alpha1 = alpha2 = 1; alpha_monotone False: an interior optimum (moving early at full speed loses balls).
sensing_* and servo_fit: how the servo sees the ball (a calibrated regime's from its calibration)."""

CALIBRATION_CAPTION = """The calibrated regimes (config robot.regimes, calibrated: true; rule calibrate_regime
fitted their sensing, servo and reach knobs to the paper's Table 2 on hits other than these) on the
{n_test} test hits: visual servoing alone by region against the paper's Table 2 (Rahmanian et al. 2023:
left 24/41, centre 60/81, right 60/101; end distance mean +- 0.5 std 12.82 +- 7.31, 6.26 +- 1.93,
10.13 +- 4.38 cm). hit_pct_ci95_*: the Clopper-Pearson 95 % interval of our rate; paper_in_ci95: the
paper's rate lies in it. hit_rate_within: within 8 points of the paper's (the issue's bar);
bar_probability_if_calibrated: the chance that a servo whose true rate is the paper's meets that bar on
this region's n test hits (binomial), i.e. what the bar can show on this many hits; all three regions at
once: {joint}. end_distance_within: the mean within the paper's mean +- 0.5 std. Knobs: {knobs}."""


def fit_summary(stats: list[dict]) -> str:
    """Servo alone by region on a calibration's fitting hits, e.g. 'left 37/63 = 59 %, 9.7 cm'."""
    return ", ".join(f"{s['region']} {s['hits']}/{s['n']} = {100 * s['hit_rate']:.0f} %, "
                     f"{s['end_distance_cm']:.1f} cm" for s in stats)


def main(ctx):
    p, o = ctx.params, ctx.output
    cells = [read_json(f, REGIME_CELL) for f in ctx.input.cells]
    table = regime_table(cells, rng_for(p["seed"], "report_regime_map"), p["n_bootstrap"])
    n_cal, n_test = cells[0]["n_calibration_hits"], len(cells[0]["controllers"]["servo"]["hit"])
    write_report_table(table, o.md, o.csv, "Robot regimes",
                       CAPTION.format(named=", ".join(p["named"]), base=p["base"], axes=p["axes"],
                                      n_cal=n_cal, n_test=n_test, n_boot=p["n_bootstrap"]))
    calibrations = [read_json(f, REGIME_CALIBRATION) for f in ctx.input.calibrations]
    calibrated = [c for c in cells if c["cell"] in {k["regime"] for k in calibrations}]
    knobs = "; ".join(f"{k['regime']}: {k['sensing']}, servo fit {k['servo_fit']}, dynamics "
                      f"{k.get('dynamics', {})}, fitted on {k['n_calibration_hits']} hits of "
                      f"{'+'.join(k['splits'])} (there: {fit_summary(k['calibration_stats'])})"
                      for k in calibrations) or "none"
    bar = calibration_table(calibrated)
    joint = "; ".join(f"{name} {rows['bar_probability_if_calibrated'].prod():.2f}"
                      for name, rows in bar.groupby("regime", sort=False)) or "none"
    write_report_table(bar, o.calibration_md, o.calibration_csv,
                       "Calibrated regimes against the paper's Table 2",
                       CALIBRATION_CAPTION.format(n_test=n_test, knobs=knobs, joint=joint))
    regime_map_figure(table, p["axes"], o.map)
    by_name = {c["cell"]: c for c in cells}
    for name, path in zip(p["named"], o.surfaces, strict=True):
        surface_figure(by_name[name], path)
