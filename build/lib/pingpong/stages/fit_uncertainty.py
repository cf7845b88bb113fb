"""Rule fit_uncertainty: every registered estimator fitted (training and calibration hits) and applied to
the calibration and test hits; one table per estimator, the fitted estimators and their models beside them."""

from pathlib import Path

from pingpong.common.artifacts import read_table, write_json, write_table
from pingpong.common.seeding import rng_for
from pingpong.curation.schemas import DATASET
from pingpong.learning.models import load_net
from pingpong.learning.schemas import PREDICTIONS
from pingpong.uncertainty.fit import (
    estimator_hits,
    estimator_tables,
    fit_estimators,
    fit_path_bands,
    fitted_record,
)
from pingpong.uncertainty.registry import UncertaintySettings
from pingpong.uncertainty.schemas import FITTED, UNCERTAINTY


def _stems(paths) -> dict[str, str]:
    """file name without .parquet / .safetensors -> path without the suffix"""
    return {Path(p).name.split(".")[0]: str(p).rsplit(".", 1)[0] for p in paths}


def main(ctx):
    settings = UncertaintySettings.from_config(ctx.params["settings"])
    members = [load_net(stem) for stem in _stems(ctx.input.members).values()]
    i = ctx.input
    dataset = read_table(i.dataset, DATASET)
    hits = estimator_hits(dataset, read_table(i.predictions, PREDICTIONS), members)
    fitted = fit_estimators(hits, settings, rng_for(ctx.params["seed"], "uncertainty"))
    prov = ctx.provenance()
    tables, paths = estimator_tables(hits, fitted), _stems(ctx.output.tables)
    for name, table in tables.items():
        write_table(table, paths[name] + ".parquet", UNCERTAINTY, prov)
    record = fitted_record(hits, fitted, settings.coverage, fit_path_bands(dataset, hits, settings.coverage))
    write_json(record, ctx.output.fitted, FITTED, prov)
    models = _stems(ctx.output.models)
    for estimator in fitted.values():
        if estimator.model_file:
            estimator.save_model(models[estimator.model_file], prov)
