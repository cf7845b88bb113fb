"""Lab data with a camera missing from a session: an error naming it before any job, unless the session
lists the cameras it has (lab.session_cameras); then the others carry on while at least two remain."""

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


def test_a_missing_camera_is_an_error_naming_it(lab_root):
    proc = snakemake(lab_root, "-n", "interim/ball3d/s00.parquet", check=False)
    assert proc.returncode != 0
    assert "raw/sessions/s00/cam2.*: missing; expected camera cam2's recording" in proc.stdout + proc.stderr
    assert "lab.session_cameras (s00: [...])" in proc.stdout + proc.stderr


def test_a_session_listing_its_cameras_triangulates_with_them(lab_root):
    write_config(lab_root, {**LAB, "lab": {**LAB["lab"], "session_cameras": {"s00": ["cam0", "cam1"]}}})
    snakemake(lab_root, "interim/ball3d/s00.parquet")
    ball = pd.read_parquet(lab_root / "interim/ball3d/s00.parquet")
    assert ball["x"].notna().sum() > 100 and ball["n_views"].max() == 2


@pytest.mark.parametrize(("listed", "said"), [
    (["cam0"], "lab.session_cameras: s00: ['cam0']; at least two cameras are needed to triangulate"),
    (["cam0", "cam9"], "lab.session_cameras: s00: 'cam9' is not in lab.cameras"),
])
def test_session_cameras_are_checked(lab_root, listed, said):
    write_config(lab_root, {**LAB, "lab": {**LAB["lab"], "session_cameras": {"s00": listed}}})
    proc = snakemake(lab_root, "-n", "interim/ball3d/s00.parquet", check=False)
    assert proc.returncode != 0 and said in proc.stdout + proc.stderr
