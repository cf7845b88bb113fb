"""Rule report_strike_error: the paper's Table 1 and the error against frames before the hit."""

from pingpong.common.artifacts import read_table
from pingpong.learning.schemas import PREDICTIONS
from pingpong.reports.strike_error import error_by_frame, plot_error_vs_frames, table1, with_mean_baseline
from pingpong.reports.tables import write_report_table

CAPTION = """Median absolute error (cm) of the strike point (x where the ball crosses y = -1.40 m) on the
test hits, by region of the true strike point, at 10 and 1 frames before the hit (the paper's Table 1)
and at the hit frame itself (0, added: the prediction the paper's robot moves on with alpha2).
`final`: the selected model refit on the training part with {seeds} seeds, predicting as their mean, on
the configured inputs (curation.inputs: causal by default, from measurements up to each frame only);
`final_zero_phase` (or `final_causal`): the same configuration and training on the other kind of inputs;
`ball_only`: the same model and training fed the ball's position alone (each a mean of {seeds} seeds);
`mean`: every hit predicted at the training hits' mean strike point. n_hits: test hits. All 31 frames
(t = -30 .. 0) are in strike_error_by_frame.md/csv and the figure."""


def main(ctx):
    by_frame = error_by_frame(with_mean_baseline(read_table(ctx.input.predictions, PREDICTIONS)))
    o, caption = ctx.output, CAPTION.format(seeds=ctx.params["seeds"])
    write_report_table(table1(by_frame), o.md, o.csv, "Strike-point error (Table 1)", caption)
    write_report_table(by_frame, o.frames_md, o.frames_csv, "Strike-point error at every frame", caption)
    plot_error_vs_frames(by_frame, o.figure)
