"""Rule report_grid_slice: the cross-validated search's winner beside the named nets of
training.grid_extra (the paper's net, the default net) on the test hits (pingpong.reports.grid_slice)."""

from pathlib import Path

import pandas as pd

from pingpong.common.artifacts import read_json, read_table
from pingpong.curation.schemas import DATASET, dataset_arrays
from pingpong.learning.cv import prediction_table
from pingpong.learning.grid import config_id
from pingpong.learning.models import load_net
from pingpong.learning.schemas import CV_RESULT, SELECTION
from pingpong.learning.train import predict_seed_mean
from pingpong.reports.grid_slice import grid_slice_table, hit_errors
from pingpong.reports.tables import write_report_table

CAPTION = """The {n_configs} configurations the search trained (config training.grid: {sample}, plus the
named nets of training.grid_extra), {n_folds}-fold cross-validated; the winner (least mean validation loss)
beside each named net on the {n_hits} test hits, each net predicting as the mean of its {n_folds} fold
models (not the final refit, so that every net is measured alike). median_cm: median absolute strike-point
error (cm) with a 95 % percentile bootstrap interval over hits; minus_winner_cm: the net's median minus the
winner's, with a paired interval (a hit keeps its frames)."""


def main(ctx):
    p = ctx.params
    dataset = read_table(ctx.input.dataset, DATASET)
    test = dataset[dataset["split"] == "test"]
    X, _ = dataset_arrays(test)
    ids = {"winner": read_json(ctx.input.selection, SELECTION)["config"]["config_id"],
           **{name: config_id(values) for name, values in p["extra"].items()}}
    results = pd.DataFrame([read_json(f, CV_RESULT) for f in ctx.input.results])
    errors, val_loss = {}, {}
    for name, cid in ids.items():
        weights = [Path(f) for f in ctx.input.cv_models if Path(f).parent.name == cid]
        nets = [load_net(str(w).removesuffix(".safetensors")) for w in weights]
        errors[name] = hit_errors(prediction_table(test, predict_seed_mean(nets, X), name))
        val_loss[name] = float(results.loc[results["config_id"] == cid, "val_loss"].mean())
    table = grid_slice_table(errors, ids, val_loss, p["seed"])
    caption = CAPTION.format(n_configs=results["config_id"].nunique(), n_folds=results["fold"].nunique(),
                             sample=f"{p['sample']} drawn at random" if p["sample"] else "all",
                             n_hits=len(test))
    write_report_table(table, ctx.output.md, ctx.output.csv, "The search's winner beside named nets", caption)
