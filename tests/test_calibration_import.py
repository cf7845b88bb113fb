"""Calibration import/export: round trips, hand-written files in the wild's layouts, clear errors."""

import textwrap

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pingpong.common.camera import Camera, look_at
from pingpong.common.rigid import apply_transform, make_transform
from pingpong.io.calibration_import import (
    change_world_frame,
    export_anipose_toml,
    export_opencv_yaml,
    read_anipose_toml,
    read_opencv_calibration,
)


def random_cameras(rng: np.random.Generator, n: int = 4) -> list[Camera]:
    cameras = []
    for c in range(n):
        R, t = look_at(rng.uniform([-4, -4, 1.5], [4, 4, 3]) + [0, 0, 0.01 * c], rng.normal(0, 0.2, 3))
        f = rng.uniform(900, 1800)
        K = np.array([[f, 0, rng.uniform(900, 1000)], [0, f * rng.uniform(0.99, 1.01), rng.uniform(500, 560)],
                      [0, 0, 1]])
        cameras.append(Camera(f"cam{c}", K, rng.normal(0, 0.05, 5), R, t, 1920, 1080))
    return cameras


def assert_same_cameras(a: list[Camera], b: list[Camera], atol: float = 1e-9) -> None:
    assert [c.name for c in a] == [c.name for c in b]
    for x, y in zip(a, b, strict=True):
        for field in ("K", "dist", "R", "t"):
            np.testing.assert_allclose(getattr(x, field), getattr(y, field), atol=atol, rtol=0, err_msg=field)
        assert (x.width, x.height) == (y.width, y.height)


@pytest.mark.parametrize("units", ["m", "mm"])
def test_anipose_toml_round_trip(tmp_path, units):
    cameras = random_cameras(np.random.default_rng(1))
    export_anipose_toml(cameras, tmp_path / "calibration.toml", units=units)
    assert_same_cameras(read_anipose_toml(tmp_path / "calibration.toml", units=units), cameras)
    assert [p.name for p in tmp_path.iterdir()] == ["calibration.toml"]  # no temporary file left


@pytest.mark.parametrize("name", ["cameras.yaml", "cameras.yml", "cameras.json"])
@pytest.mark.parametrize("units", ["m", "mm"])
def test_opencv_round_trip(tmp_path, name, units):
    cameras = random_cameras(np.random.default_rng(2))
    export_opencv_yaml(cameras, tmp_path / name, units=units)
    text = (tmp_path / name).read_text()
    assert text.lstrip().startswith("{" if name.endswith(".json") else "%YAML")
    assert_same_cameras(read_opencv_calibration(tmp_path / name, units=units), cameras)


ANIPOSE_SNIPPET = """\
[cam_0]
name = "A"
size = [ 1920, 1080,]
matrix = [ [ 1398.5, 0.0, 961.25,], [ 0.0, 1401.0, 539.5,], [ 0.0, 0.0, 1.0,],]
distortions = [ -0.125, 0.0625, 0.001, -0.002, 0.0,]
rotation = [ 1.5707963267948966, 0.0, 0.0,]
translation = [ 100.0, -250.0, 3200.0,]

[cam_1]
name = "B"
size = [ 1280, 720,]
matrix = [ [ 900.0, 0.0, 640.0,], [ 0.0, 900.0, 360.0,], [ 0.0, 0.0, 1.0,],]
distortions = [ 0.0, 0.0, 0.0, 0.0, 0.0,]
rotation = [ 0.0, 0.0, 0.0,]
translation = [ 0.0, 0.0, 0.0,]

[metadata]
adjusted = false
error = 0.0
"""


def test_hand_written_anipose_snippet(tmp_path):
    path = tmp_path / "calibration.toml"
    path.write_text(ANIPOSE_SNIPPET)
    a, b = read_anipose_toml(path, units="mm")
    assert (a.name, a.width, a.height, b.name, b.width, b.height) == ("A", 1920, 1080, "B", 1280, 720)
    np.testing.assert_array_equal(a.K, [[1398.5, 0, 961.25], [0, 1401.0, 539.5], [0, 0, 1]])
    np.testing.assert_array_equal(a.dist, [-0.125, 0.0625, 0.001, -0.002, 0.0])
    np.testing.assert_allclose(a.R, [[1, 0, 0], [0, 0, -1], [0, 1, 0]], atol=1e-15)  # 90 deg about x
    np.testing.assert_allclose(a.t, [0.1, -0.25, 3.2], atol=1e-15)  # mm -> m
    np.testing.assert_array_equal(b.R, np.eye(3))
    metres = read_anipose_toml(path, units="m")
    np.testing.assert_allclose(metres[0].t, [100.0, -250.0, 3200.0])


def test_pose2sim_snippet_with_four_distortions(tmp_path):
    path = tmp_path / "Calib.toml"
    path.write_text(textwrap.dedent("""\
        [int_cam01_img]
        name = "int_cam01_img"
        size = [ 1920.0, 1080.0]
        matrix = [ [ 1200.0, 0.0, 960.0], [ 0.0, 1200.0, 540.0], [ 0.0, 0.0, 1.0]]
        distortions = [ -0.05, 0.01, 0.0, 0.0]
        rotation = [ 0.1, -0.2, 0.3]
        translation = [ 0.5, 0.25, 4.0]
        fisheye = false

        [metadata]
        adjusted = false
        error = 0.0
        """))
    (cam,) = read_anipose_toml(path, units="m")
    assert (cam.name, cam.width, cam.height) == ("int_cam01_img", 1920, 1080)
    np.testing.assert_array_equal(cam.dist, [-0.05, 0.01, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(cam.R, Rotation.from_rotvec([0.1, -0.2, 0.3]).as_matrix(), atol=1e-14)
    np.testing.assert_array_equal(cam.t, [0.5, 0.25, 4.0])


def test_hand_written_opencv_yaml_with_common_keys(tmp_path):
    """OpenCV 4's '%YAML:1.0' header, one top-level map per camera, keys K / D / rvec / t."""
    path = tmp_path / "calib.yml"
    path.write_text(textwrap.dedent("""\
        %YAML:1.0
        ---
        left:
           image_size: [ 1280, 720 ]
           K: !!opencv-matrix
              rows: 3
              cols: 3
              dt: d
              data: [ 900., 0., 640., 0., 901., 360., 0., 0., 1. ]
           D: [ -0.1, 0.02, 0., 0. ]
           rvec: [ 0., 0., 1.5707963267948966 ]
           t: [ 0.1, 0.2, 3. ]
        right:
           width: 1920
           height: 1080
           cameraMatrix: [ [ 1400., 0., 960. ], [ 0., 1400., 540. ], [ 0., 0., 1. ] ]
           distCoeffs: !!opencv-matrix
              rows: 1
              cols: 8
              dt: d
              data: [ 0.1, -0.01, 0.001, 0.002, 0.003, 0., 0., 0. ]
           rotation_matrix: [ 1., 0., 0., 0., 1., 0., 0., 0., 1. ]
           translation: [ -100., 0., 2500. ]
        """))
    left, right = read_opencv_calibration(path, units="mm")
    assert (left.name, left.width, left.height) == ("left", 1280, 720)
    np.testing.assert_array_equal(left.K, [[900, 0, 640], [0, 901, 360], [0, 0, 1]])
    np.testing.assert_array_equal(left.dist, [-0.1, 0.02, 0, 0, 0])
    np.testing.assert_allclose(left.R, [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15)
    np.testing.assert_allclose(left.t, [1e-4, 2e-4, 3e-3])
    assert (right.name, right.width, right.height) == ("right", 1920, 1080)
    np.testing.assert_array_equal(right.dist, [0.1, -0.01, 0.001, 0.002, 0.003])
    np.testing.assert_allclose(right.t, [-0.1, 0.0, 2.5])


def test_single_camera_at_the_top_level(tmp_path):
    path = tmp_path / "cam3.json"
    path.write_text('{"camera_matrix": [[1000, 0, 500], [0, 1000, 400], [0, 0, 1]], "dist": [0, 0, 0, 0, 0],'
                    ' "R": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "tvec": [0, 0, 2], "size": [1000, 800]}')
    (cam,) = read_opencv_calibration(path, units="m")
    assert (cam.name, cam.width, cam.height) == ("cam3", 1000, 800)
    np.testing.assert_array_equal(cam.t, [0, 0, 2])


def test_change_world_frame_keeps_the_images():
    rng = np.random.default_rng(3)
    cameras = random_cameras(rng, 2)
    T_old_from_new = make_transform(Rotation.random(random_state=4).as_matrix(), [0.3, -1.0, 0.2])
    moved = change_world_frame(cameras, T_old_from_new)
    points_new = rng.uniform(-0.5, 0.5, (20, 3))
    points_old = apply_transform(T_old_from_new, points_new)
    for old, new in zip(cameras, moved, strict=True):
        np.testing.assert_allclose(new.project(points_new), old.project(points_old), atol=1e-9)


# --- errors -----------------------------------------------------------------------------------------

def test_anipose_missing_key_names_file_section_and_key(tmp_path):
    path = tmp_path / "calibration.toml"
    path.write_text(ANIPOSE_SNIPPET.replace("translation = [ 0.0, 0.0, 0.0,]\n", ""))
    with pytest.raises(ValueError, match=r"calibration\.toml: \[cam_1\]: missing key\(s\) \['translation'\]"):
        read_anipose_toml(path, units="mm")


def test_opencv_missing_key_names_file_camera_and_key(tmp_path):
    cameras = random_cameras(np.random.default_rng(5), 2)
    export_opencv_yaml(cameras, tmp_path / "cams.yaml")
    path = tmp_path / "cams.yaml"
    text = path.read_text()
    second = text.rindex("distortion_coefficients")
    path.write_text(text[:second] + "distortion_coeffs_typo" + text[second + len("distortion_coefficients"):])
    with pytest.raises(ValueError, match=r"cams\.yaml: cameras\[1\]: missing 'dist' \(one of the keys "
                                         r"\['distortion_coefficients'"):
        read_opencv_calibration(path, units="m")


@pytest.mark.parametrize(("old", "new", "message"), [
    ("[cam_1]", "[cam_1", r"calibration\.toml: not valid TOML"),
    ("size = [ 1280, 720,]", "size = [ 1280,]", r"\[cam_1\]: size must be \[width, height\]"),
    ("rotation = [ 0.0, 0.0, 0.0,]", "rotation = [ 0.0, 0.0,]", r"\[cam_1\]: rotation must"),
    ("distortions = [ 0.0, 0.0, 0.0, 0.0, 0.0,]", "distortions = [ 0.0, 0.0, 0.0, 0.0, 0.0, 0.1,]",
     r"\[cam_1\]: distortion needs 4 or 5"),
    ('name = "B"', 'name = "B"\nfisheye = true', r"\[cam_1\]: fisheye"),
    ("error = 0.0", 'error = 0.0\nunits = "m"', r"states units 'm' but 'mm'"),
])
def test_anipose_malformed(tmp_path, old, new, message):
    path = tmp_path / "calibration.toml"
    path.write_text(ANIPOSE_SNIPPET.replace(old, new))
    with pytest.raises(ValueError, match=message):
        read_anipose_toml(path, units="mm")


def test_opencv_malformed_syntax_and_missing_file(tmp_path):
    path = tmp_path / "broken.yaml"
    path.write_text("%YAML:1.0\n---\ncameras: [ { name: a\n")
    with pytest.raises(ValueError, match=r"broken\.yaml: not a readable OpenCV YAML/JSON file"):
        read_opencv_calibration(path, units="m")
    with pytest.raises(FileNotFoundError, match=r"absent\.yaml"):
        read_opencv_calibration(tmp_path / "absent.yaml", units="m")


def test_opencv_units_must_match_the_file(tmp_path):
    export_opencv_yaml(random_cameras(np.random.default_rng(6), 1), tmp_path / "c.yaml", units="mm")
    with pytest.raises(ValueError, match=r"c\.yaml: units: the file states units 'mm' but 'm'"):
        read_opencv_calibration(tmp_path / "c.yaml", units="m")
    with pytest.raises(ValueError, match="units must be one of"):
        read_opencv_calibration(tmp_path / "c.yaml", units="inch")


def test_not_a_rotation_is_refused(tmp_path):
    path = tmp_path / "c.json"
    path.write_text('{"cameras": [{"K": [1, 0, 0, 0, 1, 0, 0, 0, 1], "D": [0, 0, 0, 0], '
                    '"R": [[2, 0, 0], [0, 1, 0], [0, 0, 1]], "t": [0, 0, 1], "size": [10, 10]}]}')
    with pytest.raises(ValueError, match=r"c\.json: cameras\[0\]: rotation is not orthonormal"):
        read_opencv_calibration(path, units="m")

