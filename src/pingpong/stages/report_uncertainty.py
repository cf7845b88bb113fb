"""Rule report_uncertainty: every estimator's metrics on the test hits side by side, and the figures."""

from pingpong.common.artifacts import read_json, read_table
from pingpong.common.seeding import rng_for
from pingpong.reports.tables import write_report_table
from pingpong.reports.uncertainty import (
    by_frame_table,
    plot_error_vs_frames,
    plot_error_vs_uncertainty,
    plot_sparsification,
    plot_spearman_by_frame,
    summary_table,
)
from pingpong.reports.uncertainty_verdict import (
    COVERAGE_SLACK,
    FAR_NARROWER,
    N_BOOTSTRAP,
    PAPER_WIDTH_CM,
    hit_frame_matrix,
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

VERDICT_CAPTION = """{verdict}

Every estimator beyond the paper's three baselines (ensemble, k-NN, plain conformal) on the test hits,
at {coverage:.0%} nominal coverage. spearman_gain, ause_gain: the smallest gain over the three baselines
in within-frame Spearman (higher is better) and within-frame AUSE (lower is better); *_low95: the
lowest, over the three baselines, of the gain's 95% lower bound from {n_boot} paired bootstrap
resamples of whole test hits. A constant (plain conformal, time-to-hit and Mondrian within a frame) ranks
nothing and counts as Spearman 0. clearly_better: both lower bounds above 0; nominal_coverage: pooled
coverage within {slack:.0%} of nominal; far_narrower: mean width at most {narrow:.0f} cm ({share:.0%} of the
paper's {paper:.0f} cm); meets_all: all three."""


def main(ctx):
    tables = {path.rsplit("/", 1)[1].removesuffix(".parquet"): read_table(path, UNCERTAINTY)
              for path in ctx.input.tables}
    coverage = ctx.params["coverage"]
    caption = CAPTION.format(coverage=coverage)
    o = ctx.output
    by_frame = by_frame_table(tables)
    summary = summary_table(tables)
    write_report_table(summary, o.md, o.csv, "Uncertainty estimators", caption)
    verdict = verdict_table(tables, coverage, rng_for(ctx.params["seed"], "uncertainty_verdict"))
    text = verdict_text(verdict, summary, read_json(ctx.input.fitted, FITTED)["diagnostics"], coverage,
                        hit_frame_matrix(tables["ensemble"], "abs_error")) + "\n\n" + window_text(by_frame)
    verdict_caption = VERDICT_CAPTION.format(
        verdict=text, coverage=coverage, n_boot=N_BOOTSTRAP, slack=COVERAGE_SLACK,
        narrow=FAR_NARROWER * PAPER_WIDTH_CM, share=FAR_NARROWER, paper=PAPER_WIDTH_CM)
    write_report_table(verdict, o.verdict_md, o.verdict_csv, "Uncertainty: does any estimator beat the "
                       "paper's?", verdict_caption)
    write_report_table(by_frame, o.frames_md, o.frames_csv, "Uncertainty estimators by frame", caption)
    plot_error_vs_uncertainty(tables, o.scatter)
    plot_error_vs_frames(by_frame, tables["time_to_hit"], o.error_vs_frames)
    plot_sparsification(tables, o.sparsification)
    plot_spearman_by_frame(by_frame, o.spearman_by_frame)
