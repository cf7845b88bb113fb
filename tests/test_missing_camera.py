"""Lab data with a camera missing: the others carry on (with a warning) while at least two remain."""

import shutil

import pandas as pd
import pytest
from workflow_util import copy_checkout, snakemake, write_config

LAB = {"source": "lab", "lab": {"sessions": ["s00"], "cameras": ["cam0", "cam1", "cam2"]}}


@pytest.fixture(scope="module")
def lab_root(tiny_run, tmp_path_factory):
    """The tiny run's raw recordings as a lab would hand them over, with cam2's stream lost."""
    root = copy_checkout(tmp_path_factory.mktemp("lab"))
    shutil.copytree(tiny_run / "raw/calibration", root / "raw/calibration")
    session = root / "raw/sessions/s00"
    shutil.copytree(tiny_run / "raw/sessions/s00", session, ignore=shutil.ignore_patterns("cam2*"))
    write_config(root, LAB)
    return root


def test_a_missing_camera_is_skipped_with_a_warning(lab_root):
    proc = snakemake(lab_root, "interim/ball3d/s00.parquet")
    assert "session s00: no stream for ['cam2']; triangulating with ['cam0', 'cam1']" in proc.stderr
    ball = pd.read_parquet(lab_root / "interim/ball3d/s00.parquet")
    assert ball["x"].notna().sum() > 100 and ball["n_views"].max() == 2


def test_fewer_than_two_cameras_is_a_clear_error(lab_root):
    (lab_root / "raw/sessions/s00/cam1.mcap").unlink()
    proc = snakemake(lab_root, "interim/ball3d/s00.parquet", check=False)
    assert proc.returncode != 0
    assert "session s00: only ['cam0'] of the cameras ['cam0', 'cam1', 'cam2'] have a stream" in proc.stderr
