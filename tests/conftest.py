"""Test settings: hypothesis derandomised so that CI runs are repeatable (same examples every run),
and the small twin run that the stage tests share."""

import pytest
from hypothesis import settings
from workflow_util import copy_checkout, snakemake, write_config

settings.register_profile("repeatable", derandomize=True, deadline=None)
settings.load_profile("repeatable")

# One small twin run shared by the stage tests: 1 session of 2 rallies, 2 cameras at the default
# resolution (the perception thresholds are stated for it), 8 checkerboard views.
TINY_RUN = {"twin": {"n_sessions": 1, "rallies_per_session": 2, "n_cameras": 2, "width": 480, "height": 360,
                     "calibration_views": 8}}
TINY_TARGETS = ["raw/sessions/s00/cam0.mcap", "raw/sessions/s00/cam1.mcap", "raw/sessions/s00/optitrack.mcap",
                "raw/sessions/s00/openpose/cam0", "raw/sessions/s00/openpose/cam1",
                "interim/calibration/cameras.json", "interim/paddle/s00.parquet",
                "reports/tables/perception_accuracy.md"]


@pytest.fixture(scope="session")
def tiny_run(tmp_path_factory):
    """The checkout's workflow run on TINY_RUN; returns the run's root folder."""
    root = copy_checkout(tmp_path_factory.mktemp("tiny_run"))
    write_config(root, TINY_RUN)
    snakemake(root, *TINY_TARGETS)
    return root
