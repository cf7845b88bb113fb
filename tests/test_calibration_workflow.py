"""The calibration rule reads nothing that is not its input: views and shots in any image format, the
imported calibration and the scene-points file are inputs, so a missing one stops the dry run and an
edited one reruns the calibration (dry runs on a copy of the checkout)."""

import os
import re
from dataclasses import replace

import cv2
import numpy as np
import pytest
import yaml
from test_frame_size import write_video
from test_lab_preflight import SIZE, rig
from workflow_util import ROOT, copy_checkout, snakemake, write_config

from pingpong.io.calibration_import import export_anipose_toml

CAMS = ["cam0", "cam1"]
LAB = {"source": "lab", "lab": {"sessions": ["s00"], "cameras": CAMS, "optitrack_format": "none"}}
TARGET = "interim/calibration/cameras.json"


def lab_layout(root, views=".jpg", shot="table.tif"):
    """A lab's raw/ as far as a dry run looks (the recordings' headers, the first board view, a sample of
    the OpenPose files: pingpong.io.lab_preflight): 4 views and a table shot per camera (the shot is not
    read), a one-frame stream and its OpenPose file each."""
    image = np.zeros((SIZE[1], SIZE[0], 3), np.uint8)
    for cam in CAMS:
        folder = root / "raw/calibration" / cam
        folder.mkdir(parents=True)
        for i in range(4):
            cv2.imwrite(str(folder / f"intrinsics_{i:02d}{views}"), image)
        (folder / shot).write_bytes(b"shot")
        (root / "raw/sessions/s00/openpose" / cam).mkdir(parents=True)
        write_video([image], root / "raw/sessions/s00" / f"{cam}.mkv", SIZE[0])
        (root / "raw/sessions/s00/openpose" / cam / f"{cam}.0.json").write_text('{"people": []}')


def calibration_job(proc) -> str | None:
    """The dry run's calibration job (its lines up to the next blank one), or None when not scheduled."""
    match = re.search(r"^rule calibration:\n(.*?)(?:\n\n|\Z)", proc.stdout, re.S | re.M)
    return match.group(1) if match else None


def age(root, *paths, seconds=-100):
    """Set the files' modification times `seconds` from now (older by default)."""
    for path in paths:
        os.utime(root / path, (os.stat(root / path).st_atime, os.stat(root / path).st_mtime + seconds))


@pytest.fixture
def lab_root(tmp_path):
    root = copy_checkout(tmp_path)
    lab_layout(root)
    return root


def test_views_of_any_format_are_inputs_and_an_edited_one_reruns(lab_root):
    write_config(lab_root, LAB)
    job = calibration_job(snakemake(lab_root, "-n", TARGET))
    assert job is not None
    for cam in CAMS:
        assert all(f"raw/calibration/{cam}/intrinsics_{i:02d}.jpg" in job for i in range(4))
        assert f"raw/calibration/{cam}/table.tif" in job
    (lab_root / "interim/calibration").mkdir(parents=True)
    (lab_root / TARGET).write_text("{}")  # newer than every input: nothing to do
    assert calibration_job(snakemake(lab_root, "-n", TARGET)) is None
    age(lab_root, "raw/calibration/cam1/intrinsics_02.jpg", seconds=100)  # edited after the fit
    job = calibration_job(snakemake(lab_root, "-n", TARGET))
    assert job is not None and "Updated input files: raw/calibration/cam1/intrinsics_02.jpg" in job


def test_an_import_and_a_points_file_are_inputs(lab_root):
    write_config(lab_root, {**LAB, "perception": {"calibration_import": "raw/calibration/rig.toml",
                                                  "calibration_import_units": "mm",
                                                  "calibration_import_world": "table"}})
    export_anipose_toml([replace(c, name=n) for c, n in zip(rig(), CAMS, strict=False)],
                        lab_root / "raw/calibration/rig.toml", units="mm")
    (lab_root / "interim/calibration").mkdir(parents=True)
    (lab_root / TARGET).write_text("{}")
    assert calibration_job(snakemake(lab_root, "-n", TARGET)) is None
    age(lab_root, "raw/calibration/rig.toml", seconds=100)
    job = calibration_job(snakemake(lab_root, "-n", TARGET))
    assert job is not None and "Updated input files: raw/calibration/rig.toml" in job
    # scene points from a file: an input too, and no shot is needed
    write_config(lab_root, {**LAB, "perception": {"scene": {"mode": "subjects"}, "calibration_extrinsics": {
        "type": "points", "file": "raw/calibration/points.csv", "frame": "lab"}}})
    (lab_root / "raw/calibration/points.csv").write_text("point,x_m,y_m,z_m,cam0_u,cam0_v\n")
    job = calibration_job(snakemake(lab_root, "-n", TARGET))
    assert job is not None and "raw/calibration/points.csv" in job and "table.tif" not in job


def test_a_missing_import_stops_the_dry_run(tmp_path):
    root = copy_checkout(tmp_path)
    tiny = yaml.safe_load((ROOT / "config/test/tiny.yaml").read_text())
    write_config(root, {**tiny, "perception": {"calibration_import": "raw/calibration/rig.toml",
                                               "calibration_import_units": "m",
                                               "calibration_import_world": "table"}})
    proc = snakemake(root, "-n", TARGET, check=False)
    said = proc.stdout + proc.stderr
    assert proc.returncode != 0
    assert "MissingInputException in rule calibration" in said and "raw/calibration/rig.toml" in said


def test_two_formats_of_one_shot_stop_the_dry_run_naming_them(lab_root):
    write_config(lab_root, LAB)
    (lab_root / "raw/calibration/cam1/table.png").write_bytes(b"shot")
    proc = snakemake(lab_root, "-n", TARGET, check=False)
    assert proc.returncode != 0
    assert ("raw/calibration/cam1: several extrinsics shots ['table.png', 'table.tif']: keep one"
            in proc.stdout + proc.stderr)
