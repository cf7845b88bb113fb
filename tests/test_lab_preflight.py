"""The checks that a lab's recordings' headers and a sample can answer (pingpong.io.lab_preflight), each of
which used to stop a job after others ran, now stop the workflow when it starts, the dry run too, naming the
file: the calibration's camera names and units, the declared OpenPose model, a video's frame size against
its calibration, the scene against the calibration's world, a truncated video, a video's frames against its
OpenPose files. A synthetic pose-only lab (3 cameras of 160 x 120 px, 30 frames, one person) keeps it
small; the config check (`python -m pingpong.common.config`) names the line of a bad value and runs the same
checks."""

import json
import logging
import re
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest
import yaml
from test_camera_streams import TIMES, H, W, jpeg, square_image
from test_frame_size import READING, write_video
from test_openpose_io import STANDING
from workflow_util import DEFAULTS, ROOT, copy_checkout, snakemake

from pingpong.common.camera import Camera, look_at
from pingpong.common.config import validate_config
from pingpong.common.script import Named, StageContext
from pingpong.io.calibration_import import export_anipose_toml
from pingpong.io.lab_preflight import lab_preflight, recording_header
from pingpong.io.mcap_io import CameraStreamWriter
from pingpong.io.openpose_json import write_keypoints_json
from pingpong.perception.calibration import load_cameras
from pingpong.perception.pose3d import pose3d_table
from pingpong.perception.scene import Scene
from pingpong.stages import calibration as calibration_stage
from pingpong.stages import pose2d as pose2d_stage

NAMES = ("cam_01", "cam_02", "cam_03")
SIZE = (160, 120)  # px
N_FRAMES = 30
SESSION = "raw/sessions/lab01"
SCHEMA = ROOT / "config/schema.yaml"


def rig() -> list[Camera]:
    """Three cameras 3.5 m around a person standing at the lab's origin (floor at z = 0), with a barrel lens
    and the principal point off the image centre (a crop moves it)."""
    K = np.array([[150.0, 0.0, 81.5], [0.0, 150.0, 58.5], [0.0, 0.0, 1.0]])
    cameras = []
    for name, angle in zip(NAMES, np.radians([0, 100, 220]), strict=True):
        R, t = look_at(np.array([3.5 * np.cos(angle), 3.5 * np.sin(angle), 1.6]), np.array([0.0, 0.0, 0.9]))
        cameras.append(Camera(name, K, np.array([-0.05, 0.01, 0.0, 0.0, 0.0]), R, t, *SIZE))
    return cameras


def person_joints() -> np.ndarray:
    """(N_FRAMES, 25, 3) BODY_25 joints, m, of a person standing and swaying 1 cm a frame along x."""
    sway = np.outer(0.01 * np.arange(N_FRAMES), [1.0, 0.0, 0.0])
    return STANDING[None] + [0.0, 0.0, 0.76] + sway[:, None]


def write_lab(root, crops=None) -> None:
    """The lab's raw/: an Anipose TOML (mm, the lab's frame), a lossless video and OpenPose files per camera;
    crops: {camera: {x, y, width, height}}, recordings of that window of the calibrated image."""
    crops = crops or {}
    cameras, joints = rig(), person_joints()
    (root / "raw/calibration").mkdir(parents=True)
    export_anipose_toml(cameras, root / "raw/calibration/rig.toml", units="mm")
    for cam in cameras:
        crop = crops.get(cam.name, {"x": 0, "y": 0, "width": cam.width, "height": cam.height})
        folder = root / SESSION / "openpose" / cam.name
        folder.mkdir(parents=True)
        for frame in range(N_FRAMES):
            px = cam.project(joints[frame]) - (crop["x"], crop["y"])
            write_keypoints_json(folder, cam.name, frame, np.column_stack([px, np.full(25, 0.9)])[None])
        frames = [np.full((crop["height"], crop["width"], 3), 4 * k, np.uint8) for k in range(N_FRAMES)]
        write_video(frames, root / SESSION / f"{cam.name}.mkv", crop["width"])


def lab_config(**perception) -> dict:
    """The README's pose-only lab config for the synthetic lab; perception keys over its own."""
    return {"source": "lab",
            "lab": {"sessions": ["lab01"], "cameras": list(NAMES), "optitrack_format": "none",
                    "openpose_model": "BODY_25"},
            "perception": {"calibration_import": "raw/calibration/rig.toml", "calibration_import_units": "mm",
                           "calibration_import_world": "lab", "scene": {"mode": "subjects", "subjects": 1},
                           **perception}}


def preflight(root, config: dict) -> list[str]:
    config = validate_config(json.loads(json.dumps(config)), SCHEMA)
    return lab_preflight(root, config["lab"], config["perception"])


def truncate(path, share: float = 0.6) -> None:
    data = path.read_bytes()
    path.write_bytes(data[:int(len(data) * share)])


def drop_last_openpose_files(root, cam: str, n: int) -> None:
    for path in sorted((root / SESSION / "openpose" / cam).iterdir())[-n:]:
        path.unlink()


def narrower_video(root, cam: str, by_px: int) -> None:
    write_video([np.zeros((SIZE[1], SIZE[0], 3), np.uint8)] * N_FRAMES, root / SESSION / f"{cam}.mkv",
                SIZE[0] - by_px)


def metres_for_millimetres(root, config) -> None:
    """The TOML as Anipose writes it (no units stated, the translations in mm), configured as metres."""
    toml = root / "raw/calibration/rig.toml"
    lines = toml.read_text().splitlines(True)
    toml.write_text("".join(line for line in lines if not line.startswith("units")))
    config["perception"]["calibration_import_units"] = "m"


def set_key(section: str, **values):
    return lambda root, config: config[section].update(values)


# fault -> (what it changes in the lab's raw/ or config, what the error says, the file first)
FAULTS = {
    "camera names": (set_key("perception", calibration_import_names={"cam_1": "c1"}),
                     r"raw/calibration/rig.toml: config perception.calibration_import_names maps "
                     r"\['cam_1'\], which the file does not name; the file names "
                     r"\['cam_01', 'cam_02', 'cam_03'\]"),
    "units": (metres_for_millimetres,
              r"raw/calibration/rig.toml: .* with units 'm': is units 'm' right for a file in millimetres\?"),
    "openpose model": (set_key("lab", openpose_model="BODY_25B"),
                       r"raw/sessions/lab01/openpose/cam_01/cam_01_\d{12}_keypoints.json: keypoints declared "
                       r"BODY_25B look like BODY_25"),
    "frame size": (lambda root, config: narrower_video(root, "cam_02", 8),
                   r"raw/sessions/lab01/cam_02.mkv: frames of 152 x 120 px, but camera cam_02 is calibrated "
                   r"for 160 x 120 px in raw/calibration/rig.toml; expected the recording at the "
                   r"calibration's size, or perception.frame_crop.cam_02: \{x, y, width: 152, height: 120\}"),
    "scene against the world": (set_key("perception", scene={"mode": "players"}),
                                r"perception.scene.mode: players looks for the players at the table's ends "
                                r"in the table frame, but the calibration's world is the lab's own "
                                r"\(perception.calibration_import_world: lab\)"),
    "truncated video": (lambda root, config: truncate(root / SESSION / "cam_03.mkv"),
                        r"raw/sessions/lab01/cam_03.mkv: its header promises 30 frames, but it has data up "
                        r"to frame \d+ only: truncated"),
    "openpose files against the video": (lambda root, config: drop_last_openpose_files(root, "cam_01", 3),
                                         r"raw/sessions/lab01/cam_01.mkv: its header promises 30 frames, but "
                                         r"raw/sessions/lab01/openpose/cam_01/ holds 27 keypoints files"),
}


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    root = tmp_path_factory.mktemp("lab")
    write_lab(root)
    return root


def test_a_sound_lab_passes_in_little_time(lab):
    start = time.perf_counter()
    assert preflight(lab, lab_config()) == []
    assert time.perf_counter() - start < 2.0  # 3 cameras: ~0.1 s (the Snakefile runs it at every start)


@pytest.mark.parametrize("fault", list(FAULTS))
def test_each_late_check_now_stops_the_dry_run_naming_the_file(tmp_path, fault):
    """Each fault stops `snakemake -n` before any job, with the README's commands and paths; the sound lab's
    dry run passes."""
    root = copy_checkout(tmp_path)
    write_lab(root)
    config = lab_config()
    change, told = FAULTS[fault]
    change(root, config)
    (root / "config/lab.yaml").write_text(yaml.safe_dump(config))
    proc = snakemake(root, "-n", "interim/pose3d/lab01.parquet", configfile="config/lab.yaml", check=False)
    said = proc.stdout + proc.stderr
    assert proc.returncode != 0 and "the lab's recordings under raw/ do not match the config" in said, said
    assert re.search(told, said), said
    assert "Job stats" not in said  # stopped before the DAG, not at a job


def test_the_sound_labs_dry_run_passes(tmp_path):
    root = copy_checkout(tmp_path)
    write_lab(root)
    (root / "config/lab.yaml").write_text(yaml.safe_dump(lab_config()))
    snakemake(root, "-n", "interim/pose3d/lab01.parquet", configfile="config/lab.yaml")


def test_a_crop_makes_a_cropped_recording_fit(tmp_path):
    """cam_02 recorded 150 x 116 px from (4, 2) of its calibrated 160 x 120: refused without
    perception.frame_crop, accepted with it, and refused with a crop of another size."""
    crop = {"x": 4, "y": 2, "width": 150, "height": 116}
    write_lab(tmp_path, {"cam_02": crop})
    [problem] = preflight(tmp_path, lab_config())
    assert "cam_02.mkv: frames of 150 x 116 px, but camera cam_02 is calibrated for 160 x 120 px" in problem
    assert preflight(tmp_path, lab_config(frame_crop={"cam_02": crop})) == []
    wrong = {**crop, "width": 152}
    [problem] = preflight(tmp_path, lab_config(frame_crop={"cam_02": wrong, "cam_9": crop}))[-1:]
    assert problem.endswith("cam_02.mkv: frames of 150 x 116 px, but perception.frame_crop.cam_02 says "
                            "152 x 116 px; expected the window's size")
    assert "perception.frame_crop: 'cam_9' is not among lab.cameras" in " ".join(
        preflight(tmp_path, lab_config(frame_crop={"cam_9": crop})))


def test_a_fitted_calibrations_size_is_its_board_views(tmp_path):
    """Without an import, each camera is calibrated at its board views' size (read from the first view)."""
    write_lab(tmp_path)
    for cam in NAMES:
        width = SIZE[0] + (16 if cam == "cam_03" else 0)
        (tmp_path / "raw/calibration" / cam).mkdir()
        cv2.imwrite(str(tmp_path / "raw/calibration" / cam / "intrinsics_00.png"), np.zeros((SIZE[1], width)))
    fitted = lab_config(calibration_import=None, calibration_import_units=None, calibration_import_world=None)
    assert preflight(tmp_path, fitted) == [
        f"{tmp_path / SESSION}/cam_03.mkv: frames of 160 x 120 px, but camera cam_03 is calibrated for 176 x "
        f"120 px in {tmp_path}/raw/calibration/cam_03/intrinsics_00.png; expected the recording at the "
        "calibration's size, or perception.frame_crop.cam_03: {x, y, width: 160, height: 120} saying where "
        "its frames lie in the calibrated image"]


def config_check(root, path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pingpong.common.config", str(path), "--root", str(root)],
                          cwd=root, capture_output=True, text=True)


def test_the_config_check_names_the_line_of_a_bad_value_and_checks_the_recordings(tmp_path):
    root = copy_checkout(tmp_path)
    config = lab_config(frame_crop={"cam_02": {"x": 4, "y": 2, "width": 0, "height": 116}})
    (root / "config/lab.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    proc = config_check(root, root / "config/lab.yaml")
    line = next(n for n, text in enumerate((root / "config/lab.yaml").read_text().splitlines(), 1)
                if "width: 0" in text)
    assert proc.returncode == 1
    assert (f"config key 'perception.frame_crop.cam_02.width': 0 is less than the minimum of 1 (in "
            f"{root / 'config/lab.yaml'}, line {line})") in proc.stdout
    write_lab(root)
    (root / "config/lab.yaml").write_text(yaml.safe_dump(lab_config(scene={"mode": "players"})))
    proc = config_check(root, root / "config/lab.yaml")
    assert proc.returncode == 1 and "perception.scene.mode: players looks for the players" in proc.stdout
    (root / "config/lab.yaml").write_text(yaml.safe_dump(lab_config()))
    proc = config_check(root, root / "config/lab.yaml")
    assert proc.returncode == 0 and "(and the lab's recordings' headers under raw/)" in proc.stdout


CROP = {"x": 4, "y": 2, "width": 150, "height": 116}  # cam_02's recordings: a window of its calibrated image


def calibrated(root, crops: dict) -> Path:
    """interim/calibration/cameras.json of the calibration rule's entry on the lab's imported TOML."""
    params = {"cameras": list(NAMES), "import_units": "mm", "import_world": "lab", "import_names": {},
              "max_rms_share": DEFAULTS["perception"]["calibration_max_rms_share"], "frame_crop": crops,
              "strict": False, "take_start_ns": None, "code": ""}
    inputs = Named(calibration_import=str(root / "raw/calibration/rig.toml"), shots=[], optitrack=[])
    out = root / "interim/calibration/cameras.json"
    calibration_stage.main(StageContext("calibration", inputs, Named(cameras=str(out)), params, None))
    return out


def pose2d(root, cameras: Path, cam: str) -> pd.DataFrame:
    """The pose2d rule's entry on a camera's video and OpenPose files (it checks the frame size)."""
    inputs = Named(cameras=str(cameras), stream=str(root / SESSION / f"{cam}.mkv"), timestamps=[],
                   openpose=str(root / SESSION / "openpose" / cam))
    params = {"cam": cam, "min_confidence": 0.3, "model": "BODY_25", "pattern": "openpose",
              "reading": READING, "strict": False, "code": ""}
    out = root / f"interim/pose2d/{cam}.parquet"
    pose2d_stage.main(StageContext("pose2d", inputs, Named(pose2d=str(out)), params, None))
    return pd.read_parquet(out)


def pose3d(root, crops: dict) -> pd.DataFrame:
    """The person's joints in 3D (m), through the calibration and pose2d entries and the triangulation's
    pose3d_table."""
    path = calibrated(root, crops)
    cameras, _ = load_cameras(path)
    p = DEFAULTS["perception"]
    pose, _ = pose3d_table(cameras, [pose2d(root, path, cam) for cam in NAMES],
                           Scene.from_config({**p["scene"], "mode": "subjects"}), p["association_share"],
                           p["max_reproj_share"], p["pose_gate_noise_factor"], p["pose_confidence_weights"])
    return pose[[c for c in pose.columns if c[-2:] in ("_x", "_y", "_z")]]


def test_a_crop_triangulates_like_the_uncropped_recording(tmp_path, caplog):
    """cam_02 recorded 150 x 116 px from (4, 2) of its calibrated 160 x 120 px (frames and keypoints): with
    perception.frame_crop the calibration moves its principal point, pose2d accepts its frames and the 3D
    joints are those of the uncropped recording within 0.1 mm (the JSON's 6 significant digits round a
    keypoint by up to 5e-4 px, ~1e-5 m at 3.5 m)."""
    write_lab(tmp_path / "full")
    write_lab(tmp_path / "cropped", {"cam_02": CROP})
    full = pose3d(tmp_path / "full", {})
    with caplog.at_level(logging.WARNING):
        cropped = pose3d(tmp_path / "cropped", {"cam_02": CROP})
    assert ("cam_02: calibrated at 160 x 120 px, recorded at 150 x 116 px from (4, 2) px of it (config "
            "perception.frame_crop): principal point moved to (77.5, 56.5) px") in caplog.text
    assert full.notna().all().all() and len(full) == N_FRAMES
    np.testing.assert_allclose(cropped.to_numpy(), full.to_numpy(), rtol=0, atol=1e-4)
    points = full.to_numpy().reshape(N_FRAMES, -1, 1, 3)  # each a true joint of its frame's, within 1 mm
    assert (np.linalg.norm(points - person_joints()[:, None], axis=-1).min(axis=-1) < 1e-3).all()


def test_an_mcap_streams_header_is_its_summary_and_first_image(tmp_path):
    with CameraStreamWriter(tmp_path / "cam.mcap", 0, "cam0") as writer:
        for t, image in zip(TIMES, [square_image(i) for i in range(3)], strict=False):
            writer.add(t, jpeg(image))
    assert recording_header(tmp_path / "cam.mcap", None) == ((W, H), 3, "")
