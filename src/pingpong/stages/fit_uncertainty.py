"""Rule fit_uncertainty: every estimator fitted (training and calibration hits) and applied to the
calibration and test hits; one table per estimator, the fitted estimators beside them."""

import numpy as np

from pingpong.common.artifacts import read_table, write_json, write_table
from pingpong.common.seeding import rng_for
from pingpong.curation.dataset import DATASET, dataset_arrays
from pingpong.learning.cv import PREDICTIONS
from pingpong.learning.models import FRAMES_BEFORE_HIT, load_net
from pingpong.learning.train import predict, strike_points
from pingpong.uncertainty.error_head import save_error_head
from pingpong.uncertainty.estimators import fit_estimators, frame_rows
from pingpong.uncertainty.features import frame_features
from pingpong.uncertainty.knn import save_knn
from pingpong.uncertainty.quantile_heads import save_heads
from pingpong.uncertainty.tables import FITTED, UNCERTAINTY


def _json_safe(value):
    """+inf (too few calibration hits for the nominal coverage) as null: JSON has no infinity."""
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def main(ctx):
    p = ctx.params
    settings = p["settings"]
    dataset = read_table(ctx.input.dataset, DATASET)
    rows = frame_rows(dataset, read_table(ctx.input.predictions, PREDICTIONS))
    X, _ = dataset_arrays(dataset)
    features = frame_features(X, FRAMES_BEFORE_HIT)
    members = [load_net(f.removesuffix(".safetensors")) for f in ctx.input.members]
    ensemble_strike = np.stack([strike_points(predict(net, X)).reshape(-1) for net in members])
    heads_settings = {"hidden": settings["quantile_hidden"], "epochs": settings["quantile_epochs"]}
    error_head_settings = {"hidden": settings["error_head_hidden"], "epochs": settings["error_head_epochs"]}
    tables, fitted, models = fit_estimators(rows, features, X, ensemble_strike, settings["coverage"],
                                            settings["knn_k"], heads_settings, error_head_settings,
                                            rng_for(p["seed"], "uncertainty"))
    prov = ctx.provenance()
    for path in ctx.output.tables:
        write_table(tables[path.rsplit("/", 1)[1].removesuffix(".parquet")], path, UNCERTAINTY, prov)
    write_json(_json_safe(fitted), ctx.output.fitted, FITTED, prov)
    save_knn(models["knn"], ctx.output.knn.removesuffix(".safetensors"), prov)
    save_heads(models["quantile_heads"], ctx.output.heads.removesuffix(".safetensors"), prov)
    save_error_head(models["error_head"], ctx.output.error_head.removesuffix(".safetensors"), prov)
