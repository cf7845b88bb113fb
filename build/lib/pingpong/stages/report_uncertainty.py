"""Rule report_uncertainty: every estimator's metrics on the test hits side by side, and the figures."""

from pingpong.common.artifacts import read_json, read_table
from pingpong.common.seeding import rng_for
from pingpong.curation.schemas import DATASET
from pingpong.learning.schemas import PREDICTIONS
from pingpong.reports.tables import write_report_table
from pingpong.reports.uncertainty import (
    ORACLE,
    by_frame_table,
    path_band_report,
    plot_coverage_by_width,
    plot_error_vs_frames,
    plot_error_vs_uncertainty,
    plot_sparsification,
    plot_spearman_by_frame,
    plot_spearman_oracle_by_frame,
    summary_table,
    with_oracle,
)
from pingpong.reports.uncertainty_oracle import join_test_hits, read_oracles
from pingpong.reports.uncertainty_verdict import (
    COVERAGE_SLACK,
    MIN_TERCILE_COVERAGE,
    N_BOOTSTRAP,
    NARROWER,
    ORACLE_BAR,
    verdict_table,
    verdict_text,
    window_text,
)
from pingpong.uncertainty.schemas import FITTED, UNCERTAINTY

CAPTION = """Uncertainty of the strike-point prediction (final model) on the test hits, at {coverage:.0%}
nominal coverage. Spearman: rank correlation of the uncertainty with the absolute error, pooled over the 31
frames t = -30 .. 0 and within each frame (mean over frames; pooled alone rewards knowing the time).
AUSE: area between the sparsification curve and the oracle's (mean error left after removing the most
uncertain share, divided by the mean error; 0 = ranks like the errors). Coverage and mean width of the
intervals pooled, and the lowest and highest coverage over the frames; width_cv: coefficient of
variation of the widths. NaN: the estimator is constant (no ranking) or gives no interval; inf: too few
calibration hits for the nominal coverage. The paper's estimators (paper = True): ensemble std over
members with different seeds, split conformal with one width, k-NN regressor of the error from the
inputs, time-to-hit trend; beyond it: Mondrian conformal per frame, normalised conformal on the k-NN
error, the ensemble spread or a learned error head (a small GRU trained on the training hits'
out-of-fold errors, also shown alone as error_head), conformalised quantile regression (CQR).
Calibration by hit."""

PATH_CAPTION = """Bands for the whole predicted path (the two lines a1, a2, b on the table, at every 5 cm of y
from +1.40 to -1.40 m) on the test hits at {coverage:.0%} nominal coverage, beside the strike point's.
simultaneous: one band per frame before the hit whose coverage holds for the whole path at once (the score
is the largest deviation over y, each y scaled by the training hits' mean out-of-fold deviation there, one
conformal quantile per frame from the calibration hits); pointwise: a conformal interval at each y alone,
which covers each point but the whole path less often. whole_path_coverage: share of test (hit, frame) rows
whose true path lies inside at every y (overall, and in the worst frame, worst_frame); strike_point_coverage:
at y = -1.40 m; mean_half_width_cm over y and rows, strike_half_width_cm at the strike line."""

VERDICT_CAPTION = """{verdict}

Every estimator on the test hits at {coverage:.0%} nominal coverage. spearman_oracle_1_20: within-frame
Spearman between the uncertainty and the twin's oracle std (the spread of the strike x over what the player
had not yet chosen), the mean over frames 1-20 before the hit, with its 95 % interval (oracle_low95,
oracle_high95) from {n_boot} paired bootstrap resamples of whole test hits (n_oracle_hits: test hits with an
oracle); gain_over_paper: its gain over the paper's best estimator at this (paper_baseline), paired;
spearman_error: within-frame Spearman with the absolute error over all 31 frames (a constant within a frame
counts as 0). coverage, coverage_min_width_tercile (the worst of the three width terciles), mean_width_cm
and width_vs_conformal (over plain conformal's) from the summary table. The bars: recovers_oracle
(spearman_oracle_1_20 >= {oracle_bar}); nominal_coverage (within {slack:.0%} of nominal);
conditional_coverage (>= {tercile:.0%} in every width tercile); narrower (at most {narrower} of plain
conformal's width); meets_all: all four. Without an oracle (a lab run) its columns are empty."""


def main(ctx):
    i, o = ctx.input, ctx.output
    estimators = {path.rsplit("/", 1)[1].removesuffix(".parquet"): read_table(path, UNCERTAINTY)
                  for path in i.tables}
    dataset, predictions = read_table(i.dataset, DATASET), read_table(i.predictions, PREDICTIONS)
    oracle_rows = None
    if i.oracle:  # twin runs: the strike oracle, mirrored like the hits
        oracle_rows = join_test_hits(dataset, predictions, read_oracles(ctx.params["sessions"], i.oracle))
    tables = with_oracle(estimators, oracle_rows)
    coverage = ctx.params["coverage"]
    caption = CAPTION.format(coverage=coverage)
    by_frame = by_frame_table(tables)
    summary = summary_table(tables, coverage)
    write_report_table(summary, o.md, o.csv, "Uncertainty estimators", caption)
    fitted = read_json(i.fitted, FITTED)
    write_report_table(path_band_report(fitted["path_band"], dataset, predictions), o.path_md, o.path_csv,
                       "Uncertainty of the whole path", PATH_CAPTION.format(coverage=coverage))
    estimators_only = {name: t for name, t in tables.items() if name != ORACLE}
    rng = rng_for(ctx.params["seed"], "uncertainty_verdict")
    verdict = verdict_table(estimators_only, summary, coverage, rng)
    text = verdict_text(verdict, summary, fitted["diagnostics"], coverage) + "\n\n" + window_text(
        by_frame[by_frame["estimator"] != ORACLE])
    verdict_caption = VERDICT_CAPTION.format(
        verdict=text, coverage=coverage, n_boot=N_BOOTSTRAP, oracle_bar=ORACLE_BAR, slack=COVERAGE_SLACK,
        tercile=MIN_TERCILE_COVERAGE, narrower=NARROWER)
    write_report_table(verdict, o.verdict_md, o.verdict_csv, "Uncertainty: which estimator recovers what "
                       "could be known?", verdict_caption)
    write_report_table(by_frame, o.frames_md, o.frames_csv, "Uncertainty estimators by frame", caption)
    plot_error_vs_uncertainty(tables, o.scatter)
    plot_error_vs_frames(by_frame, tables["time_to_hit"], o.error_vs_frames)
    plot_sparsification(estimators_only, o.sparsification)
    plot_spearman_by_frame(by_frame, o.spearman_by_frame)
    plot_spearman_oracle_by_frame(by_frame, o.spearman_oracle_by_frame)
    plot_coverage_by_width(estimators_only, o.coverage_by_width)
