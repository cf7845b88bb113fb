"""Rule report_uncertainty: every estimator's metrics on the test hits side by side, and the figures."""

from pingpong.common.artifacts import read_table
from pingpong.common.script import run_stage
from pingpong.reports.tables import write_report_table
from pingpong.reports.uncertainty import (
    by_frame_table,
    plot_error_vs_frames,
    plot_error_vs_uncertainty,
    plot_sparsification,
    summary_table,
)
from pingpong.uncertainty.tables import UNCERTAINTY

CAPTION = """Uncertainty of the strike-point prediction (final model) on the test hits, at {coverage:.0%}
nominal coverage. Spearman: rank correlation of the uncertainty with the absolute error, pooled over the 30
frames before the hit and within each frame (mean over frames; pooled alone rewards knowing the time).
AUSE: area between the sparsification curve and the oracle's (mean error left after removing the most
uncertain share, divided by the mean error; 0 = ranks like the errors). Coverage and mean width of the
intervals pooled, and the lowest and highest coverage over the frames; width_cv: coefficient of
variation of the widths. NaN: the estimator is constant (no ranking) or gives no interval; inf: too few
calibration hits for the nominal coverage. The paper's estimators (paper = True): ensemble std over
members with different seeds, split conformal with one width, k-NN regressor of the error from the
inputs, time-to-hit trend; beyond it: Mondrian conformal per frame, normalised conformal on the k-NN
error or the ensemble spread, conformalised quantile regression (CQR). Calibration by hit."""


def main(ctx):
    tables = {path.rsplit("/", 1)[1].removesuffix(".parquet"): read_table(path, UNCERTAINTY)
              for path in ctx.input.tables}
    caption = CAPTION.format(coverage=ctx.params["coverage"])
    o = ctx.output
    by_frame = by_frame_table(tables)
    write_report_table(summary_table(tables), o.md, o.csv, "Uncertainty estimators", caption)
    write_report_table(by_frame, o.frames_md, o.frames_csv, "Uncertainty estimators by frame", caption)
    plot_error_vs_uncertainty(tables, o.scatter)
    plot_error_vs_frames(by_frame, tables["time_to_hit"], o.error_vs_frames)
    plot_sparsification(tables, o.sparsification)


run_stage(main, globals().get("snakemake"), "report_uncertainty")
