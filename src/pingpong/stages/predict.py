"""Rule predict: per hit and frame before the hit, the trajectory parameters and the strike point.

Test and calibration hits: the final model (and, for the reports, the ball-only baseline and the
final model refit on the other kind of inputs, on those inputs). Training hits: out of fold, each
predicted by the selected configuration's model that did not train on it.
"""

import pandas as pd

from pingpong.common.artifacts import read_json, read_table, write_table
from pingpong.curation.dataset import dataset_arrays
from pingpong.curation.schemas import DATASET
from pingpong.learning.cv import BALL_ONLY, prediction_table
from pingpong.learning.models import load_net
from pingpong.learning.schemas import PREDICTIONS, SELECTION
from pingpong.learning.train import predict


def _stem(weights_path: str) -> str:
    return weights_path.removesuffix(".safetensors")


def main(ctx):
    dataset = read_table(ctx.input.dataset, DATASET)
    best = read_json(ctx.input.selection, SELECTION)["config"]["config_id"]
    X, _ = dataset_arrays(dataset)
    held_out = (dataset["split"] != "train").to_numpy()
    final, ball_only, other = (load_net(_stem(f)) for f in (ctx.input.final, ctx.input.ball_only,
                                                            ctx.input.other_final))
    X_other, _ = dataset_arrays(read_table(ctx.input.other_dataset, DATASET))
    test = dataset[held_out]
    parts = [prediction_table(test, predict(final, X[held_out]), "final"),
             prediction_table(test, predict(ball_only, X[held_out][..., BALL_ONLY]), "ball_only"),
             prediction_table(test, predict(other, X_other[held_out]), ctx.params["other_final"])]
    for stem in (_stem(f) for f in ctx.input.cv_models if f"/{best}/" in f):
        fold = int(stem.rsplit("fold", 1)[1])
        rows = ((dataset["split"] == "train") & (dataset["fold"] == fold)).to_numpy()
        parts.append(prediction_table(dataset[rows], predict(load_net(stem), X[rows]), "final"))
    write_table(pd.concat(parts, ignore_index=True), ctx.output.predictions, PREDICTIONS, ctx.provenance())
