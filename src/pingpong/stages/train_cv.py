"""Rule train_cv: one (configuration, fold) job of the cross-validated grid search."""

from pingpong.common.artifacts import read_table, write_json
from pingpong.curation.schemas import DATASET, dataset_arrays
from pingpong.learning.cv import TrainSettings, fit_fold
from pingpong.learning.models import save_net
from pingpong.learning.schemas import CV_RESULT


def main(ctx):
    p = ctx.params
    dataset = read_table(ctx.input.dataset, DATASET)
    train = dataset[dataset["split"] == "train"]
    X, Y = dataset_arrays(train)
    settings = TrainSettings.from_config(p["settings"])
    net, result = fit_fold(X, Y, train["fold"].to_numpy(), p["fold"], p["config"], settings, p["seed"])
    prov = ctx.provenance()
    save_net(net, {**p["config"], "fold": p["fold"]}, ctx.output.model.removesuffix(".safetensors"), prov)
    write_json(result, ctx.output.result, CV_RESULT, prov)
