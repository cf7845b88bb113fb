"""Test settings: hypothesis derandomised so that CI runs are repeatable (same examples every run),
and the small twin run that the stage tests share."""

import pytest
from hypothesis import settings
from workflow_util import copy_checkout, snakemake, write_config

settings.register_profile("repeatable", derandomize=True, deadline=None)
settings.load_profile("repeatable")

# One small run of the whole default workflow shared by the stage tests: 1 session of 8 short rallies, 3
# cameras at the default resolution (the perception thresholds are stated for it; with 2 cameras too
# many joints are seen once only), 8 checkerboard views, and a one-configuration grid trained for a
# few epochs (the wiring is tested here, not the model).
TINY_RUN = {
    "twin": {"n_sessions": 1, "rallies_per_session": 8, "n_cameras": 3, "width": 480, "height": 360,
             "calibration_views": 8,
             # the former default fault rates: short rallies, so 8 of them fill every split and fold
             "fault_rates": {"net": 0.05, "out": 0.05, "double_bounce": 0.02, "miss": 0.05}},
    "training": {"grid": {"cell": ["gru"], "rnn_hidden": [16], "mlp_hidden": [32]}, "n_folds": 3,
                 "max_epochs": 4, "patience": 4},
    "uncertainty": {"ensemble_size": 2, "quantile_epochs": 50},
    # 2 calibration hits make the normalised conformal factor infinite; the k-NN error stays finite
    "robot": {"estimator": "knn"},
}


@pytest.fixture(scope="session")
def tiny_run(tmp_path_factory):
    """The checkout's workflow run on TINY_RUN; returns the run's root folder."""
    root = copy_checkout(tmp_path_factory.mktemp("tiny_run"))
    write_config(root, TINY_RUN)
    snakemake(root)  # rule all
    return root
