"""A random slice of the paper's grid (training.grid_sample) and the winner beside named nets
(training.grid_extra, rule report_grid_slice)."""

import re

import numpy as np
import pandas as pd
import pytest
from conftest import TINY_RUN
from workflow_util import copy_checkout, snakemake, write_config

from pingpong.common.artifacts import read_json
from pingpong.common.script import Named, StageContext
from pingpong.curation.schemas import HIT_KEYS
from pingpong.learning.schemas import SELECTION
from pingpong.reports.grid_slice import grid_slice_table
from pingpong.reports.summary import TABLE1_FRAMES
from pingpong.stages import report_grid_slice as stage


def _errors(rng, n_hits, shift_cm):
    index = pd.MultiIndex.from_tuples([("s00", r, 0) for r in range(n_hits)], names=HIT_KEYS)
    base = pd.DataFrame(rng.gamma(2.0, 10.0, size=(n_hits, len(TABLE1_FRAMES))), index=index,
                        columns=list(TABLE1_FRAMES))
    return base, base + shift_cm


def test_a_net_worse_on_every_hit_shows_its_gap_with_an_interval_that_excludes_zero():
    winner, worse = _errors(np.random.default_rng(1), 200, 5.0)
    table = grid_slice_table({"winner": winner, "paper_net": worse}, {"winner": "a", "paper_net": "b"},
                             {"winner": 3.0, "paper_net": 3.5}, seed=0, n_resamples=500)
    assert list(table["net"].unique()) == ["winner", "paper_net"] and len(table) == 2 * len(TABLE1_FRAMES)
    own = table[table["net"] == "winner"]
    assert (own["minus_winner_cm"] == 0).all() and (own["low_cm"] <= own["median_cm"]).all()
    other = table[table["net"] == "paper_net"]
    assert np.allclose(other["minus_winner_cm"], 5.0)  # a shift moves the median by itself
    assert (other["minus_winner_low_cm"] > 0).all() and (other["minus_winner_high_cm"] >= 5.0).all()


def test_the_stage_on_the_tiny_run_compares_the_winner_with_a_named_net(tiny_run, tmp_path):
    """The tiny grid's own configuration named as an extra: it is the winner, so its gap is exactly 0."""
    selection = read_json(tiny_run / "processed/models/selection.json", SELECTION)["config"]
    extra = {"same": {k: v for k, v in selection.items() if k != "config_id"}}
    models = sorted(str(p) for p in (tiny_run / "processed/models/cv").glob("*/fold*.safetensors"))
    results = sorted(str(p) for p in (tiny_run / "processed/models/cv").glob("*/fold*_result.json"))
    inputs = Named(dataset=str(tiny_run / "processed/dataset.parquet"), results=results, cv_models=models,
                   selection=str(tiny_run / "processed/models/selection.json"))
    out = Named(md=str(tmp_path / "g.md"), csv=str(tmp_path / "g.csv"))
    params = {"extra": extra, "sample": None, "seed": 1}
    stage.main(StageContext("report_grid_slice", inputs, out, params, None))
    table = pd.read_csv(out.csv)
    assert set(table["net"]) == {"winner", "same"}
    assert table["config_id"].nunique() == 1  # the named net is the grid's one configuration
    assert (table["minus_winner_cm"] == 0).all() and (table["n_hits"] > 0).all()
    assert "1 configurations" in (tmp_path / "g.md").read_text()


@pytest.mark.slow
def test_a_grid_sample_schedules_that_many_configurations_plus_the_named_nets(tmp_path):
    root = copy_checkout(tmp_path)
    grid = {"cell": ["rnn", "lstm", "gru"], "rnn_hidden": [8, 16, 32, 64]}
    training = {**TINY_RUN["training"], "grid": grid, "grid_sample": 5, "grid_extra": {"outside": {
                    "cell": "gru", "rnn_hidden": 12, "lr": 0.001, "rnn_layers": 2, "mlp_hidden": 32,
                    "mlp_layers": 2, "dropout": 0.1, "velocity": False}}}
    write_config(root, {**TINY_RUN, "training": training}, "slice.yaml")  # the tiny run's, but its grid
    out = snakemake(root, "-n", configfile="config/slice.yaml")
    jobs = re.findall(r"^train_cv\s+(\d+)$", out.stdout, re.M)
    assert set(jobs) == {str((5 + 1) * TINY_RUN["training"]["n_folds"])}, jobs  # (job stats print twice)
    assert re.search(r"^report_grid_slice\s+1$", out.stdout, re.M)
