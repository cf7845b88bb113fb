"""Rule select_model: the grid's CV table, and the configuration with the best mean validation loss."""

import numpy as np
import pandas as pd

from pingpong.common.artifacts import read_json, write_json
from pingpong.learning.grid import grid_summary, select_best
from pingpong.learning.schemas import CV_RESULT, SELECTION
from pingpong.reports.tables import write_report_table

CAPTION = """{n_folds}-fold cross-validation of every configuration of the grid (config `training.grid`) on
the training part: mean and standard deviation of the validation loss (the paper's loss: summed
absolute error in m over 24 points of the path, averaged over the 31 frames t = -30 .. 0), best first.
The first row is the configuration refit on the whole training part."""


def main(ctx):
    results = pd.DataFrame([read_json(f, CV_RESULT) for f in ctx.input.results])
    summary = grid_summary(results)
    configs = pd.DataFrame(ctx.params["configs"])
    table = summary.merge(configs, on="config_id", how="left")
    caption = CAPTION.format(n_folds=results["fold"].nunique())
    write_report_table(table, ctx.output.md, ctx.output.csv, "Cross-validated grid search", caption)
    best = select_best(results)
    epochs = int(np.median(results.loc[results["config_id"] == best, "best_epoch"]))
    config = configs[configs["config_id"] == best].iloc[0].to_dict()
    write_json({"config": config, "epochs": max(epochs, 1)}, ctx.output.selection, SELECTION,
               ctx.provenance())
