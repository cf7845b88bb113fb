"""A lab session as a lab would bring it, run through the ball and pose stages: video files (one with
container times, two with timestamp CSVs), OpenPose JSON in the dotted per-frame layout, an imported
Anipose TOML calibration in millimetres, and no OptiTrack. Built from the tiny twin run, so the result
is checked against that run's own 3D ball and joints."""

import shutil

import numpy as np
import pandas as pd
import pytest
import yaml
from lab_util import CODEC, dotted_openpose
from workflow_util import copy_checkout, snakemake

from pingpong.io.calibration_import import export_anipose_toml
from pingpong.perception.calibration import load_cameras

CAMERAS = ["cam0", "cam1", "cam2"]


@pytest.fixture(scope="module")
def lab_run(tiny_run, tiny_video, tmp_path_factory):
    root = copy_checkout(tmp_path_factory.mktemp("lab_session"))
    session = root / "raw/sessions/lab01"
    session.mkdir(parents=True)
    twin = tiny_run / "raw/sessions/s00"
    for k, cam in enumerate(CAMERAS):
        suffix = ("mp4", "mkv", "mp4")[k] if CODEC == "libx264" else "mkv"
        video, times = tiny_video(cam, suffix)
        shutil.copyfile(video, session / f"{cam}.{suffix}")
        if k:  # cam0: the container's times from lab.video_start_ns on; cam1, cam2: a CSV of camera times
            pd.DataFrame({"time_ns": times}).to_csv(session / f"{cam}_timestamps.csv", index=False)
        dotted_openpose(twin / "openpose" / cam, session / "openpose" / cam, cam)
    cameras, _ = load_cameras(tiny_run / "interim/calibration/cameras.json")
    rig = root / "raw/calibration/rig.toml"
    export_anipose_toml([c for c in cameras if c.name in CAMERAS], rig, units="mm")
    config = {"source": "lab",
              "lab": {"sessions": ["lab01"], "cameras": CAMERAS, "optitrack_format": "none",
                      "video_start_ns": {"lab01": int(times[0])}},
              "perception": {"calibration_import": "raw/calibration/rig.toml",
                             "calibration_import_units": "mm", "calibration_import_world": "table"}}
    (root / "config/lab.yaml").write_text(yaml.safe_dump(config))
    snakemake(root, "interim/pose3d/lab01.parquet", configfile="config/lab.yaml")
    return root


def test_the_lab_session_reaches_3d_without_optitrack(lab_run):
    assert not (lab_run / "interim/paddle").exists()
    calibration = load_cameras(lab_run / "interim/calibration/cameras.json")[1]
    assert calibration["T_table_from_optitrack"] is None
    sync = pd.read_parquet(lab_run / "interim/sync/lab01.parquet")
    assert list(sync["camera"]) == CAMERAS and (sync["frames"] == sync["frames"][0]).all()
    log = (lab_run / "logs/detection/lab01_cam1.log").read_text()
    assert "camera stream format video" in log


def test_3d_ball_and_joints_match_the_twin_run(lab_run, tiny_run):
    """The same OpenPose output and calibration give the same joints; the ball, detected on the video's
    frames, lands within millimetres of the one detected on the twin's JPEG frames."""
    runs = ((lab_run, "lab01"), (tiny_run, "s00"))
    pose = [pd.read_parquet(r / f"interim/pose3d/{s}.parquet") for r, s in runs]
    xyz = [c for c in pose[1].columns if c.endswith(("_x", "_y", "_z"))]
    assert np.nanmax(np.abs(pose[0][xyz].to_numpy() - pose[1][xyz].to_numpy())) < 1e-6  # m
    ball = [pd.read_parquet(r / f"interim/ball3d/{s}.parquet") for r, s in runs]
    assert (ball[0]["time_ns"].to_numpy() == ball[1]["time_ns"].to_numpy()).all()
    seen = [b["x"].notna().to_numpy() for b in ball]
    assert abs(seen[0].mean() - seen[1].mean()) < 0.01  # share of frames with a 3D ball
    both = seen[0] & seen[1]
    lab, twin = (b.loc[both, list("xyz")].to_numpy() for b in ball)
    gap = np.linalg.norm(lab - twin, axis=1)
    assert np.median(gap) < 0.003  # m
