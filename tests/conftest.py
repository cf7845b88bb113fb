"""Test settings: hypothesis derandomised so that CI runs are repeatable (same examples every run),
and the small twin run that the stage tests share."""

import math
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import settings
from workflow_util import ROOT, copy_checkout, snakemake

settings.register_profile("repeatable", derandomize=True, deadline=None)
settings.load_profile("repeatable")

# The suite's temporary folders (the tiny run, the lab layouts, the workflow copies) at their peak, GB: with
# pyproject's tmp_path_retention_policy (docs/performance.md, "CI"). A full disk fails the tests that copy
# recordings with copy errors far from the cause: said first, where it is short.
SUITE_DISK_GB = 8


def pytest_sessionstart(session):
    folder = Path(session.config.option.basetemp or tempfile.gettempdir()).resolve()
    existing = next(p for p in (folder, *folder.parents) if p.exists())  # --basetemp is made later
    free = shutil.disk_usage(existing).free / 2**30
    line = f"free disk under {folder}: {free:.1f} GB; the suite's temporary folders take ~{SUITE_DISK_GB} GB"
    if free < SUITE_DISK_GB:
        line = f"WARNING: {line}: tests that copy recordings will fail with copy errors"
    session.config.pluginmanager.get_plugin("terminalreporter").write_line(line)


# One small run of the whole default workflow shared by the stage tests: config/test/tiny.yaml (its comments
# say what it is and why).
TINY_CONFIG = "config/test/tiny.yaml"
TINY_RUN = yaml.safe_load((ROOT / TINY_CONFIG).read_text())


@pytest.fixture(scope="session")
def tiny_run(tmp_path_factory):
    """The checkout's workflow run on the tiny config; returns the run's root folder. For iterating on one
    test only, PINGPONG_TINY_RUN may name a finished tiny run to reuse (never set in CI: its artifacts may
    be of older code)."""
    if os.environ.get("PINGPONG_TINY_RUN"):
        return Path(os.environ["PINGPONG_TINY_RUN"])
    root = copy_checkout(tmp_path_factory.mktemp("tiny_run"))
    snakemake(root, configfile=TINY_CONFIG)  # rule all
    return root


@pytest.fixture(scope="session")
def tiny_video(tiny_run, tmp_path_factory):
    """The tiny run's camera `cam` of session s00 as a video file (tests/lab_util.py), made once per (cam,
    suffix) for all the lab tests: a function (cam, suffix) -> (its path, frame times), the file to be copied,
    not changed. A camera is encoded once (write_video, ~22 s on 2 cores) and remuxed into other containers:
    the two lab layouts' six videos cost three encodings."""
    from lab_util import remux, write_video

    folder, encoded, made = tmp_path_factory.mktemp("tiny_videos"), {}, {}

    def video(cam: str, suffix: str) -> tuple[Path, np.ndarray]:
        if (cam, suffix) not in made:
            path = folder / f"{cam}.{suffix}"
            if cam in encoded:
                remux(encoded[cam][0], path)
                made[cam, suffix] = path, encoded[cam][1]
            else:
                mcap = tiny_run / f"raw/sessions/s00/{cam}.mcap"
                made[cam, suffix] = encoded[cam] = path, write_video(mcap, path)
        return made[cam, suffix]

    return video


@pytest.fixture(scope="session")
def twin_stream():
    """Camera 0's frames of a 2-rally twin session (tests/twin_util.py: seed 5, 3,340 frames at 480x360,
    JPEG q90, 100 Hz) and its ball truth, rendered once (~18 s) for the detector tests of test_detection and
    test_ball_track: to be read, not changed."""
    import twin_util

    return twin_util.twin_stream(5, 2, 480, 360)


@pytest.fixture(scope="module")
def reader():
    """The fuzz tests' reader calls in a child process (tests/fuzz_util.py), one child per test module."""
    from fuzz_util import IsolatedReader

    isolated = IsolatedReader(timeout_s=10)
    yield isolated
    isolated.close()


def coverage_bounds(n_cal: int, coverages: np.ndarray, alpha: float) -> tuple[float, float]:
    """Split conformal with n exchangeable calibration scores (no ties): 1 - alpha <= E[coverage] <=
    1 - alpha + 1/(n + 1); widened by 4 standard errors of the mean coverage over the trials given."""
    slack = 4 * np.std(coverages) / math.sqrt(len(coverages))
    return 1 - alpha - slack, 1 - alpha + 1 / (n_cal + 1) + slack


def pytest_sessionfinish(session, exitstatus):
    """With PINGPONG_FUZZ_TABLE set to a path, the fuzz tests' counts per reader written there (the table of
    docs/fuzz.md: `PINGPONG_FUZZ_TABLE=docs/fuzz_table.md .venv/bin/pytest -q tests -k fuzz`)."""
    from fuzz_util import TABLE, table_markdown

    if os.environ.get("PINGPONG_FUZZ_TABLE") and TABLE:
        Path(os.environ["PINGPONG_FUZZ_TABLE"]).write_text(table_markdown())
