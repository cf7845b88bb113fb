"""Rule train_final: one seed of a final model, the selected configuration refit on the whole training
part (the ball-only baseline: fed the ball alone; final_{other inputs}: on the other kind of inputs)."""

from pingpong.common.artifacts import read_json, read_table
from pingpong.curation.schemas import DATASET, dataset_arrays
from pingpong.learning.cv import BALL_ONLY, TrainSettings, refit
from pingpong.learning.models import save_net
from pingpong.learning.schemas import SELECTION


def main(ctx):
    p = ctx.params
    selection = read_json(ctx.input.selection, SELECTION)
    dataset = read_table(ctx.input.dataset, DATASET)
    X, Y = dataset_arrays(dataset[dataset["split"] == "train"])
    if p["ball_only"]:
        X = X[..., BALL_ONLY]
    settings = TrainSettings.from_config(p["settings"])
    net = refit(X, Y, selection["config"], selection["epochs"], settings, p["seed"])
    save_net(net, {**selection["config"], "epochs": selection["epochs"], "ball_only": p["ball_only"],
                   "seed": p["seed"]},
             ctx.output.model.removesuffix(".safetensors"), ctx.provenance())
