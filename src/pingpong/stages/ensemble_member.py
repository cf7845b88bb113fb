"""Rule ensemble_member: the selected configuration refit on the training part with seed + member."""

from pingpong.common.artifacts import read_json, read_table
from pingpong.curation.dataset import dataset_arrays
from pingpong.curation.schemas import DATASET
from pingpong.learning.cv import TrainSettings, refit
from pingpong.learning.models import save_net
from pingpong.learning.schemas import SELECTION


def main(ctx):
    p = ctx.params
    selection = read_json(ctx.input.selection, SELECTION)
    dataset = read_table(ctx.input.dataset, DATASET)
    X, Y = dataset_arrays(dataset[dataset["split"] == "train"])
    seed = p["seed"] + p["member"]
    settings = TrainSettings.from_config(p["settings"])
    net = refit(X, Y, selection["config"], selection["epochs"], settings, seed)
    save_net(net, {**selection["config"], "epochs": selection["epochs"], "member": p["member"], "seed": seed},
             ctx.output.model.removesuffix(".safetensors"), ctx.provenance())
