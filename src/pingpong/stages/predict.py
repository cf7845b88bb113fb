"""Rule predict: per hit and frame before the hit, the trajectory parameters and the strike point.

Test and calibration hits: the final model, the mean of its seeds (and, for the reports, the ball-only
baseline and the final model refit on the other kind of inputs, on those inputs, each a mean of as
many seeds). Training hits: out of fold, each predicted by the selected configuration's model that
did not train on it (one seed: the cross-validation's).
"""

from pathlib import Path

import pandas as pd

from pingpong.common.artifacts import read_json, read_table, write_table
from pingpong.curation.schemas import DATASET, dataset_arrays
from pingpong.learning.cv import BALL_ONLY, prediction_table
from pingpong.learning.models import load_net
from pingpong.learning.schemas import PREDICTIONS, SELECTION
from pingpong.learning.train import predict, predict_seed_mean


def _net(weights):
    return load_net(str(weights).removesuffix(".safetensors"))


def _nets(weights_paths) -> list:
    return [_net(weights) for weights in weights_paths]


def main(ctx):
    i = ctx.input
    dataset = read_table(i.dataset, DATASET)
    best = read_json(i.selection, SELECTION)["config"]["config_id"]
    X, _ = dataset_arrays(dataset)
    held_out = (dataset["split"] != "train").to_numpy()
    X_other, _ = dataset_arrays(read_table(i.other_dataset, DATASET))
    test = dataset[held_out]
    parts = [prediction_table(test, predict_seed_mean(_nets(i.final), X[held_out]), "final"),
             prediction_table(test, predict_seed_mean(_nets(i.ball_only), X[held_out][..., BALL_ONLY]),
                              "ball_only"),
             prediction_table(test, predict_seed_mean(_nets(i.other_final), X_other[held_out]),
                              ctx.params["other_final"])]
    for weights in (Path(f) for f in i.cv_models if Path(f).parent.name == best):
        fold = int(weights.stem.removeprefix("fold"))
        rows = ((dataset["split"] == "train") & (dataset["fold"] == fold)).to_numpy()
        parts.append(prediction_table(dataset[rows], predict(_net(weights), X[rows]), "final"))
    write_table(pd.concat(parts, ignore_index=True), ctx.output.predictions, PREDICTIONS, ctx.provenance())
