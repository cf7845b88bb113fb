"""TRC marker files (pingpong.io.trc, rule pose_trc) read back by a reader written here from the format's
documentation (OpenSim's "Marker (.trc) Files" page: three header lines, marker names over X/Y/Z column
labels, a blank line, then Frame# Time X1 Y1 Z1 ... per frame, tab-separated; OpenSim's TRCFileAdapter
reads an empty cell as a missing marker and wants 2 + 3 x markers cells a row), not from the writer."""

import numpy as np
import pandas as pd
import pytest
from test_openpose_io import STANDING, write_model_json

from pingpong.common.artifacts import Provenance, write_table
from pingpong.common.script import Named, StageContext
from pingpong.frames import BODY25
from pingpong.io.openpose_json import pose_keypoints
from pingpong.io.trc import opensim_axes, write_trc
from pingpong.perception.pose2d import pose2d_table
from pingpong.perception.pose3d import pose3d_table
from pingpong.perception.scene import default_players_scene
from pingpong.perception.schemas import POSE3D
from pingpong.stages import pose_trc
from pingpong.twin.rig import make_rig
from pingpong.twin.truth import JOINT_COLUMNS

PRECISION_M = 0.5e-6  # half the last written decimal of a value in metres


def read_trc(path) -> tuple[dict, list[str], np.ndarray, np.ndarray, np.ndarray]:
    """(header {key: value}, marker names, frame numbers (F,), times (F,) s, points (F, M, 3): NaN where
    missing)."""
    lines = path.read_text().split("\n")
    assert lines[0].split("\t")[:3] == ["PathFileType", "4", "(X/Y/Z)"]
    header = dict(zip(lines[1].split("\t"), lines[2].split("\t"), strict=True))
    labels = [cell for cell in lines[3].split("\t") if cell]
    assert labels[:2] == ["Frame#", "Time"]
    markers = labels[2:]
    coordinates = [f"{a}{k}" for k in range(1, len(markers) + 1) for a in "XYZ"]
    assert [c for c in lines[4].split("\t") if c] == coordinates
    assert lines[5] == ""  # the blank line before the data
    rows = [line.split("\t") for line in lines[6:] if line]  # (and the final newline)
    assert all(len(row) == 2 + 3 * len(markers) for row in rows)
    values = np.array([[float(cell) if cell else np.nan for cell in row[2:]] for row in rows])
    frames = np.array([int(row[0]) for row in rows])
    times = np.array([float(row[1]) for row in rows])
    return header, markers, frames, times, values.reshape(len(rows), len(markers), 3)


def test_markers_read_back_as_written(tmp_path):
    rng = np.random.default_rng(0)
    points = rng.uniform(-3, 3, (50, 4, 3))
    points[5, 1] = np.nan  # a marker missing in a frame
    points[7:9] = np.nan  # every marker missing
    time_s = 0.01 * np.arange(50)
    path = tmp_path / "subject.trc"
    write_trc(path, time_s, ["RShoulder", "RElbow", "Nose", "LHip"], points)
    header, markers, frames, times, read = read_trc(path)
    assert path.read_text().split("\n")[0].split("\t")[3] == "subject.trc"
    assert header["NumFrames"] == "50" and header["NumMarkers"] == "4" and header["Units"] == "m"
    assert float(header["DataRate"]) == float(header["CameraRate"]) == 100.0
    assert header["OrigDataStartFrame"] == "1"
    assert markers == ["RShoulder", "RElbow", "Nose", "LHip"]
    assert frames.tolist() == list(range(1, 51))
    np.testing.assert_allclose(times, time_s, atol=PRECISION_M)
    assert (np.isnan(read) == np.isnan(points)).all()
    np.testing.assert_allclose(read, points, atol=PRECISION_M)


def test_refuses_what_no_reader_could_split(tmp_path):
    with pytest.raises(ValueError, match="marker names"):
        write_trc(tmp_path / "a.trc", np.zeros(2), ["R Shoulder", "L\tHip"], np.zeros((2, 2, 3)))
    with pytest.raises(ValueError, match="do not fit"):
        write_trc(tmp_path / "a.trc", np.zeros(3), ["Nose"], np.zeros((2, 1, 3)))


def _trc_of(pose3d, slot: str, out):
    """Rule pose_trc's file of a slot of the pose3d table at path pose3d, read back (read_trc)."""
    pose_trc.main(StageContext("pose_trc", Named(pose3d=str(pose3d)), Named(trc=str(out)), {"slot": slot},
                               None))
    return read_trc(out)


# BODY_25B's keypoints that BODY_25 has no name for, about the neck (m): below the chin, the top of the head
BODY25B_OWN = {"UpperNeck": (0.0, -0.03, 0.08), "HeadTop": (0.0, -0.02, 0.30)}


def test_a_body25b_keypoint_without_a_body25_name_reaches_the_trc(tmp_path):
    """BODY_25B JSON of a standing near player seen by 4 cameras (0.3 px noise) through pose2d, pose3d and
    rule pose_trc: the keypoints BODY_25 has no name for (UpperNeck, HeadTop) are triangulated from every
    view and written as markers named by the model, in its order, where the player's are (within 1 cm)."""
    body = STANDING + [0.2, 2.3, 0.0]
    neck = body[BODY25.index("Neck")]
    names = pose_keypoints("BODY_25B")
    truth = np.array([body[BODY25.index(n)] if n in BODY25 else neck + BODY25B_OWN[n] for n in names])
    time_ns = 10_000_000 * np.arange(20, dtype=np.int64)
    cameras, rng = make_rig(np.random.default_rng(1), 4, 480, 360), np.random.default_rng(2)
    tables = []
    for camera in cameras:
        (tmp_path / camera.name).mkdir()
        for frame in range(len(time_ns)):
            px = camera.project(truth) + rng.normal(0, 0.3, (len(names), 2))
            person = np.column_stack([px, np.full(len(names), 0.9)])
            write_model_json(tmp_path / camera.name / f"{camera.name}.{frame:05d}.json", [person])
        tables.append(pose2d_table(tmp_path / camera.name, time_ns, model="BODY_25B"))
    pose, _ = pose3d_table(cameras, tables, default_players_scene(), 0.02, 0.005, 4.0, False)
    write_table(pose, tmp_path / "pose3d.parquet", POSE3D, Provenance.of("triangulation"))
    near = pose[pose["player"] == "near"]
    _, markers, _, _, points = _trc_of(tmp_path / "pose3d.parquet", "near", tmp_path / "near.trc")
    assert markers == list(names) and markers[17:19] == list(BODY25B_OWN)
    for name in BODY25B_OWN:
        assert (near[f"{name}_views"] == 4).all() and (near[f"{name}_reproj_px"] < 1.5).all()
        k = names.index(name)
        assert np.linalg.norm(points[:, k] - opensim_axes(truth[k]), axis=1).max() < 0.01, name


def test_a_players_trc_is_the_pose3d_table(tiny_run, tmp_path):
    """Rule pose_trc on the tiny run's pose3d: one marker per BODY_25 keypoint (the twin's model), named
    by it, in metres on the camera clock; OpenSim's y-up axes are the table frame's (y, z, x)."""
    source = tiny_run / "interim/pose3d/s00.parquet"
    header, markers, _, times, points = _trc_of(source, "near", tmp_path / "near.trc")
    pose = pd.read_parquet(source)
    near = pose[pose["player"] == "near"].sort_values("time_ns")
    assert markers == list(BODY25) and header["Units"] == "m" and float(header["DataRate"]) == 100.0
    assert int(header["NumFrames"]) == len(near)
    np.testing.assert_allclose(times, (near["time_ns"] - near["time_ns"].iloc[0]) * 1e-9, atol=PRECISION_M)
    expected = np.stack([near[[f"{m}_{a}" for a in "yzx"]].to_numpy() for m in markers], axis=1)
    assert np.isfinite(expected).any()
    assert (np.isnan(points) == np.isnan(expected)).all()
    np.testing.assert_allclose(points, expected, atol=PRECISION_M)


def test_every_body25_keypoint_is_in_pose3d(tiny_run):
    """The tiny run's pose3d holds all 25 keypoints of the twin's BODY_25 with views and reprojection
    errors; each is fitted nearly always for one player at least (the near player's feet are mostly hidden
    from the twin's cameras) and lies near the twin's truth (median under 10 cm, face and feet too)."""
    pose = pd.read_parquet(tiny_run / "interim/pose3d/s00.parquet")
    people = pd.read_parquet(tiny_run / "raw/twin_truth/s00/people.parquet").set_index(["person", "time_ns"])
    true = people.loc[list(zip(pose["player"], pose["time_ns"], strict=True))]
    for k, name in enumerate(BODY25):
        assert {f"{name}_{q}" for q in ("x", "y", "z", "views", "reproj_px")} <= set(pose.columns)
        fitted = pose[f"{name}_views"] >= 2
        assert fitted.groupby(pose["player"]).mean().max() > 0.9, name
        assert pose.loc[fitted, f"{name}_reproj_px"].notna().all()
        xyz = pose[[f"{name}_{a}" for a in "xyz"]].to_numpy()
        truth = true[list(JOINT_COLUMNS[3 * k:3 * k + 3])].to_numpy()
        assert np.nanmedian(np.linalg.norm(xyz - truth, axis=1)) < 0.10, name
