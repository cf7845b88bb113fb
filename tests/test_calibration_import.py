"""Calibration import/export: round trips, hand-written files in the wild's layouts, clear errors; and the
calibration stage run on an import alone, placed in the table frame and checked by reprojection."""

import logging
import re
import textwrap

import cv2
import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from pingpong.common.camera import Camera, look_at
from pingpong.common.patterns import TABLE_MARKERS
from pingpong.common.rigid import apply_transform, make_transform
from pingpong.common.script import Named, StageContext
from pingpong.frames import TABLE_HALF_LENGTH, TABLE_HALF_WIDTH
from pingpong.io.calibration_import import (
    CalibrationFileError,
    change_world_frame,
    export_anipose_toml,
    export_opencv_yaml,
    read_anipose_toml,
    read_opencv_calibration,
)
from pingpong.perception.calibration import (
    CalibrationError,
    load_cameras,
    optitrack_record,
    table_from_optitrack,
)
from pingpong.stages import calibration as stage
from pingpong.twin.calibration_images import render_table_view
from pingpong.twin.render import make_lab
from pingpong.twin.rig import make_rig


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
    with pytest.raises(ValueError, match=r"calibration\.toml: camera A is 3211 m from the world origin "
                                         r"\(expected within 20 m\) with units 'm': is units 'm' right for a "
                                         r"file in millimetres\?"):
        read_anipose_toml(path, units="m")


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


HAND_WRITTEN_YAML = textwrap.dedent("""\
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
    """)


def test_hand_written_opencv_yaml_with_common_keys(tmp_path):
    """OpenCV 4's '%YAML:1.0' header, one top-level map per camera, keys K / D / rvec / t."""
    path = tmp_path / "calib.yml"
    path.write_text(HAND_WRITTEN_YAML)
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
    ("size = [ 1280, 720,]", "size = [ 1280,]", r"\[cam_1\]: key 'size': must be \[width, height\]"),
    ("rotation = [ 0.0, 0.0, 0.0,]", "rotation = [ 0.0, 0.0,]", r"\[cam_1\]: key 'rotation': rotation must"),
    ("distortions = [ 0.0, 0.0, 0.0, 0.0, 0.0,]", "distortions = [ 0.0, 0.0, 0.0, 0.0, 0.0, 0.1,]",
     r"\[cam_1\]: key 'distortions': distortion needs 4 or 5"),
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
    with pytest.raises(ValueError, match=r"c\.json: cameras\[0\]: key 'R': rotation is not orthonormal"):
        read_opencv_calibration(path, units="m")


# Issue 37: implausible values that were read as cameras; each now a CalibrationFileError naming the camera
TOML_WRONG_VALUES = [  # (old, new, the key named, message)
    ("size = [ 1280, 720,]", "size = [ 0, 0,]", "size", r"image size must be whole pixels from 1 to 65535"),
    ("size = [ 1280, 720,]", "size = [ 1280.5, 720,]", "size", r"image size must be whole pixels"),
    ("size = [ 1280, 720,]", 'size = [ "1280", 720,]', "size", r"image size: expected numbers, got '1280'"),
    ("size = [ 1280, 720,]", "size = 1280", "size", r"must be \[width, height\], got 1280"),
    ("[ 900.0, 0.0, 640.0,]", "[ nan, 0.0, 640.0,]", "matrix", r"camera matrix: expected finite numbers"),
    ("[ 900.0, 0.0, 640.0,]", "[ -1.0, 0.0, 640.0,]", "matrix", r"focal lengths fx -1, fy 900: expected"),
    ("[ 900.0, 0.0, 640.0,]", "[ 0.0, 0.0, 640.0,]", "matrix", r"focal lengths fx 0, fy 900: expected"),
    ("[ 900.0, 0.0, 640.0,]", "[ 90.0, 0.0, 640.0,]", "matrix", r"focal lengths fx 90, fy 900: .* factor"),
    ("[ 900.0, 0.0, 640.0,]", "[ true, 0.0, 640.0,]", "matrix", r"camera matrix: expected numbers, got True"),
    ("[ 900.0, 0.0, 640.0,]", "[ 900.0, 0.0, 6400.0,]", "matrix",
     r"principal point \(6400, 360\) outside the 1280x720"),
    ("[ 0.0, 0.0, 1.0,],]\ndistortions = [ 0.0", "[ 0.0, 1.0, 1.0,],]\ndistortions = [ 0.0", "matrix",
     r"camera matrix must be \[\[fx, s, cx\], \[0, fy, cy\], \[0, 0, 1\]\]"),
    ("[ 0.0, 900.0, 360.0,]", "[ 0.0, 900.0,]", "matrix", r"camera matrix: rows of unequal length"),
    ("rotation = [ 0.0, 0.0, 0.0,]", "rotation = [ inf, 0.0, 0.0,]", "rotation",
     r"rotation: expected finite numbers"),
    ("translation = [ 0.0, 0.0, 0.0,]", "translation = [ 0.0, nan, 0.0,]", "translation",
     r"translation: expected finite"),
    ("translation = [ 0.0, 0.0, 0.0,]", "translation = [ 0.0, 0.0,]", "translation",
     r"need a 3-vector translation, got 2 values"),
]


@pytest.mark.parametrize(("old", "new", "key", "message"), TOML_WRONG_VALUES)
def test_anipose_implausible_values_are_refused(tmp_path, old, new, key, message):
    path = tmp_path / "calibration.toml"
    assert old in ANIPOSE_SNIPPET
    path.write_text(ANIPOSE_SNIPPET.replace(old, new))
    with pytest.raises(CalibrationFileError, match=rf"calibration\.toml: \[cam_1\]: key '{key}': " + message):
        read_anipose_toml(path, units="mm")


def test_anipose_camera_name_must_be_a_string(tmp_path):
    path = tmp_path / "calibration.toml"
    path.write_text(ANIPOSE_SNIPPET.replace('name = "B"', "name = 2"))
    with pytest.raises(CalibrationFileError, match=r"toml: \[cam_1\]: name must be a string, got 2"):
        read_anipose_toml(path, units="mm")


def test_anipose_metadata_not_a_table_and_bytes_not_utf8(tmp_path):
    path = tmp_path / "calibration.toml"
    path.write_text("metadata = 3\n" + ANIPOSE_SNIPPET.split("[metadata]")[0])
    with pytest.raises(CalibrationFileError, match=r"calibration\.toml: \[metadata\]: expected a table"):
        read_anipose_toml(path, units="mm")
    path.write_bytes(ANIPOSE_SNIPPET.encode().replace(b'"A"', b'"\xff"'))
    with pytest.raises(CalibrationFileError, match=r"calibration\.toml: not valid TOML \(UnicodeDecodeError"):
        read_anipose_toml(path, units="mm")


OPENCV_WRONG_VALUES = [  # in the hand-written YAML's camera 'left' (K an !!opencv-matrix, dt d)
    ("dt: d\n      data: [ 900.", "dt: u\n      data: [ 900.", r"key 'K': matrix dt 'u': expected one of"),
    ("dt: d\n      data: [ 900.", "dt: i\n      data: [ 900.", r"key 'K': matrix dt 'i'"),
    ("cols: 3", "cols: -1", r"key 'K': matrix rows 3.0, cols -1.0: expected whole numbers from 1"),
    ("cols: 3", "cols: 1000000", r"key 'K': matrix rows 3.0, cols 1000000.0: expected"),
    ("      cols: 3\n", "", r"key 'K': a map with keys \['data', 'dt', 'rows'\] where a matrix"),
    ("[ 900., 0., 640.,", "[ 0., 640.,", r"key 'K': matrix of 3x3: expected a list of 9 numbers as data, "
                                          r"got 8"),
    ("[ 900., 0., 640.,", "[ .nan, 0., 640.,", r"key 'K': camera matrix: expected finite numbers"),
    ("[ 900., 0., 640.,", "[ -1., 0., 640.,", r"key 'K': focal lengths fx -1, fy 901: expected positive"),
    ("[ 900., 0., 640.,", "[ null, 0., 640.,", r"key 'K': an empty entry where a number"),
    ("[ 900., 0., 640.,", '[ "900", 0., 640.,', r"key 'K': matrix data: expected numbers"),
    ("image_size: [ 1280, 720 ]", "image_size: [ 0, 0 ]", r"key 'image_size': image size must be whole"),
    ("image_size: [ 1280, 720 ]", "image_size: [ 1280 ]", r"key 'image_size': image size must be \[width, "),
    ("D: [ -0.1, 0.02, 0., 0. ]", "D: [ -0.1, .inf, 0., 0. ]", r"key 'D': distortion: expected finite"),
    ("t: [ 0.1, 0.2, 3. ]", "t: [ 0.1, 0.2 ]", r"key 't': need a 3-vector translation, got 2 values"),
    ("t: [ 0.1, 0.2, 3. ]", "t: [ [ [ 0.1 ] ], 0.2, 3. ]", r"key 't': lists nested deeper than"),
]


@pytest.mark.parametrize(("old", "new", "message"), OPENCV_WRONG_VALUES)
def test_opencv_implausible_values_and_matrix_headers_are_refused(tmp_path, old, new, message):
    path = tmp_path / "calib.yml"
    text = HAND_WRITTEN_YAML.split("right:")[0]
    assert old in text
    path.write_text(text.replace(old, new))
    with pytest.raises(CalibrationFileError, match=r"calib\.yml: left: " + message):
        read_opencv_calibration(path, units="mm")


# Issue 48: a held-out fuzz run's findings, read as cameras without a word; each now a CalibrationFileError


def test_a_toml_distortion_one_value_short_is_named(tmp_path):
    """[k1 k2 p1 p2 k3] with one value lost reads as a valid 4-coefficient model: the cameras must agree."""
    path = tmp_path / "calibration.toml"
    path.write_text(ANIPOSE_SNIPPET.replace("distortions = [ 0.0, 0.0, 0.0, 0.0, 0.0,]",
                                            "distortions = [ 0.0, 0.0, 0.0, 0.0,]"))
    with pytest.raises(CalibrationFileError, match=r"calibration\.toml: \[cam_1\]: key 'distortions': 4 "
                                                   r"distortion coefficients where \[cam_0\] has 5; "
                                                   "expected 5 for every camera of the file"):
        read_anipose_toml(path, units="mm")


def test_a_plain_list_distortion_one_value_short_is_named(tmp_path):
    """The same in OpenCV JSON where the distortion is a plain list (no matrix header declares its count);
    the hand-written YAML's matrix of 8 beside a list of 4 stays readable (test above)."""
    camera = '"K": [900, 0, 640, 0, 900, 360, 0, 0, 1], "R": [0, 0, 0], "size": [1280, 720]'
    path = tmp_path / "c.json"
    path.write_text(f'{{"a": {{{camera}, "D": [0.1, 0, 0, 0, 0], "t": [0, 0, 3]}}, '
                    f'"b": {{{camera}, "D": [0.1, 0, 0, 0], "t": [1, 0, 3]}}}}')
    with pytest.raises(CalibrationFileError, match=r"c\.json: b: key 'D': 4 distortion coefficients where a "
                                                   "has 5; expected 5"):
        read_opencv_calibration(path, units="m")


def test_two_toml_cameras_of_one_name_are_named(tmp_path):
    path = tmp_path / "calibration.toml"
    path.write_text(ANIPOSE_SNIPPET.replace('name = "B"', 'name = "A"'))
    with pytest.raises(CalibrationFileError, match=r"calibration\.toml: two cameras named 'A' "
                                                   r"\(\[cam_0\] and \[cam_1\]\); expected each name once"):
        read_anipose_toml(path, units="mm")


@pytest.mark.parametrize("layout", ["sequence", "top-level maps"])
def test_two_opencv_cameras_of_one_name_are_named(tmp_path, layout):
    """A 'cameras' sequence naming one camera twice, or one top-level key twice (FileStorage keeps both
    and reads the first)."""
    path = tmp_path / "calib.yml"
    if layout == "sequence":
        export_opencv_yaml(random_cameras(np.random.default_rng(8), 3), path, units="mm")
        path.write_text(path.read_text().replace("name: cam2", "name: cam0"))
        places = r"cameras\[0\] and cameras\[2\]"
    else:
        path.write_text(HAND_WRITTEN_YAML.replace("right:", "left:"))
        places = "left and left"
    name = "cam0" if layout == "sequence" else "left"
    with pytest.raises(CalibrationFileError, match=rf"calib\.yml: two cameras named '{name}' \({places}\)"):
        read_opencv_calibration(path, units="mm")


@pytest.mark.parametrize("suffix", ["yaml", "json"])
def test_opencv_booleans_are_refused_where_filestorage_reads_them_as_1_or_0(tmp_path, suffix):
    export_opencv_yaml(random_cameras(np.random.default_rng(8), 2), tmp_path / f"c.{suffix}")
    text = (tmp_path / f"c.{suffix}").read_text()
    focal = re.search(r'data"?: \[ (\d+\.\d+)', text).group(1)
    (tmp_path / f"c.{suffix}").write_text(text.replace(focal, "true", 1))
    with pytest.raises(CalibrationFileError, match=rf"c\.{suffix}: line \d+: 'true' where a number or a "
                                                   r"string was expected \(OpenCV would read it as 1\)"):
        read_opencv_calibration(tmp_path / f"c.{suffix}", units="m")
    (tmp_path / f"c.{suffix}").write_text(text.replace('name: cam0', 'name: "true"'))  # a string: fine
    assert read_opencv_calibration(tmp_path / f"c.{suffix}", units="m")[0].name == (
        "true" if suffix == "yaml" else "cam0")



METRES_AS_MM = (r"cameras cam0 and cam1 \d+(\.\d+)? mm apart \(expected 0\.3 to 30 m\) with units 'mm': "
                r"is units 'mm' right for a file in metres\?")
MM_AS_METRES = r"camera cam\d is \d+ m from the world origin .* is units 'm' right for a file in millimetres"


@pytest.mark.parametrize(("written", "asked", "message"),
                         [("m", "mm", METRES_AS_MM), ("mm", "m", MM_AS_METRES)])
def test_units_off_by_1000_name_the_units(tmp_path, written, asked, message):
    cameras = random_cameras(np.random.default_rng(7), 3)
    toml, yaml = tmp_path / "c.toml", tmp_path / "c.yaml"
    export_anipose_toml(cameras, toml, units=written)
    toml.write_text(toml.read_text().replace(f'units = "{written}"\n', ""))  # files that state no units
    export_opencv_yaml(cameras, yaml, units=written)
    yaml.write_text(yaml.read_text().replace(f"units: {written}\n", "").replace(f'units: "{written}"\n', ""))
    for path, read in [(toml, read_anipose_toml), (yaml, read_opencv_calibration)]:
        with pytest.raises(ValueError, match=message):
            read(path, units=asked)
    with pytest.raises(ValueError, match=message):
        run_import(tmp_path, toml, "table", units=asked, names=["cam0"])


# --- the calibration stage on an import alone ------------------------------------------------------------

NAMES = ["cam0", "cam1", "cam2", "cam3"]
TABLE_CORNERS = np.array([[sx * TABLE_HALF_WIDTH, sy * TABLE_HALF_LENGTH, 0.0]
                          for sx, sy in [(1, 1), (-1, 1), (-1, -1), (1, -1)]])  # table frame, m
NET_ENDS = np.array([[0.9144, 0.0, 0.1525], [-0.9144, 0.0, 0.1525]])  # the net posts' tops, m


def run_import(tmp_path, path, world, units="m", shots=(), names=NAMES, max_rms_share=0.002, name_map=None):
    """The calibration stage's main on an import, with the table shots `shots` (one per camera) if any."""
    params = {"cameras": names, "folders": [str(tmp_path / n) for n in names], "import_units": units,
              "import_world": world, "import_names": name_map or {}, "extrinsics": "table_mat", "board": None,
              "fit_k3": None, "source": "lab", "max_rms_share": max_rms_share, "frame_crop": {},
              "strict": False, "take_start_ns": None, "code": ""}
    inputs = Named(calibration_import=str(path), shots=[str(s) for s in shots])  # no optitrack
    out = tmp_path / "cameras.json"
    stage.main(StageContext("calibration", inputs, Named(cameras=str(out)), params, None))
    return load_cameras(out)


def in_world(cameras: list[Camera]) -> tuple[list[Camera], np.ndarray]:
    """The cameras as a calibration with its own world frame (Anipose's) has them, and T_table_from_world."""
    T_table_from_world = make_transform(Rotation.random(random_state=8).as_matrix(), [1.5, -2.0, 0.8])
    return change_world_frame(cameras, T_table_from_world), T_table_from_world


def test_import_alone_in_the_table_frame_runs_unchecked(tmp_path, caplog):
    cameras = random_cameras(np.random.default_rng(9))
    export_anipose_toml(cameras, tmp_path / "calibration.toml")
    with caplog.at_level(logging.WARNING, logger="pingpong.perception.calibration"):
        loaded, payload = run_import(tmp_path, tmp_path / "calibration.toml", "table")
    assert_same_cameras(loaded, cameras)
    assert payload["import_checks"] == [] and "imported calibration is UNCHECKED" in caplog.text
    assert payload["T_table_from_optitrack"] is None
    assert "no OptiTrack" in payload["T_table_from_optitrack_reason"]


def test_import_in_the_labs_own_frame_is_kept_and_said(tmp_path, caplog, twin_shots):
    """world: lab (a pose-only lab): the file's frame is kept as it is, cameras.json says world_frame lab, and
    table shots are not checked against it (their corners are table points)."""
    cameras, shots = twin_shots
    world_cameras, _ = in_world(cameras)
    export_anipose_toml(world_cameras, tmp_path / "calibration.toml", units="mm")
    with caplog.at_level(logging.WARNING, logger="pingpong.perception.calibration"):
        loaded, payload = run_import(tmp_path, tmp_path / "calibration.toml", "lab", units="mm", shots=shots,
                                     names=["cam0", "cam1"])
    assert_same_cameras(loaded, world_cameras, atol=1e-9)
    assert payload["world_frame"] == "lab" and payload["import_checks"] == []
    assert "world frame: the lab's own" in caplog.text and "there is no table frame" in caplog.text


def test_import_alone_with_a_table_from_world_transform(tmp_path):
    cameras = random_cameras(np.random.default_rng(10))
    world_cameras, T_table_from_world = in_world(cameras)
    export_opencv_yaml(world_cameras, tmp_path / "calibration.yaml", units="mm")
    world = {"T_table_from_world": T_table_from_world.tolist()}
    loaded, _ = run_import(tmp_path, tmp_path / "calibration.yaml", world, units="mm")
    assert_same_cameras(loaded, cameras, atol=1e-9)


def table_points(cameras: list[Camera], seen: dict[str, np.ndarray]) -> list[dict]:
    """The config's table_points: each point with its pixels in the cameras that `seen` says see it."""
    points = np.vstack([TABLE_CORNERS, NET_ENDS])
    by_name = {c.name: c for c in cameras}
    return [{"xyz_m": p.tolist(), "pixels": {name: by_name[name].project(p)[0].tolist()
                                             for name, which in seen.items() if i in which}}
            for i, p in enumerate(points) if any(i in which for which in seen.values())]


def test_import_alone_placed_by_table_points(tmp_path):
    cameras = random_cameras(np.random.default_rng(11))
    world_cameras, _ = in_world(cameras)
    export_anipose_toml(world_cameras, tmp_path / "calibration.toml")
    # cam0 sees the four corners, cam1 two of them and a net post; cam2 and cam3 none
    points = table_points(cameras, {"cam0": [0, 1, 2, 3], "cam1": [0, 3, 4]})
    loaded, payload = run_import(tmp_path, tmp_path / "calibration.toml", {"table_points": points})
    assert_same_cameras(loaded, cameras, atol=1e-6)
    assert [c["camera"] for c in payload["import_checks"]] == ["cam0", "cam1"]
    assert max(c["rms_px"] for c in payload["import_checks"]) < 1e-3


def test_table_points_fail_the_check_when_a_camera_was_moved(tmp_path):
    cameras = random_cameras(np.random.default_rng(11))
    world_cameras, _ = in_world(cameras)
    tilt = Rotation.from_rotvec([0.0, np.radians(1.0), 0.0]).as_matrix()  # cam1 turned by 1 deg
    moved = Camera("cam1", world_cameras[1].K, world_cameras[1].dist, tilt @ world_cameras[1].R,
                   tilt @ world_cameras[1].t, 1920, 1080)
    export_anipose_toml([world_cameras[0], moved, *world_cameras[2:]], tmp_path / "calibration.toml")
    points = table_points(cameras, {"cam0": [0, 1, 2, 3], "cam1": [0, 2, 3, 4]})
    message = (r"cam\d: the calibration reprojects the listed table points \(which placed the rig\) at "
               r"\d+\.\d+ px RMS, over the 4\.41 px limit \(0\.002 of the 1920x1080 image's diagonal")
    with pytest.raises(CalibrationError, match=message):
        run_import(tmp_path, tmp_path / "calibration.toml", {"table_points": points})


@pytest.fixture(scope="module")
def twin_shots(tmp_path_factory):
    """Two of the twin's cameras (table frame) and their table.png shots of the ChArUco mat."""
    folder = tmp_path_factory.mktemp("twin_shots")
    cameras = make_rig(np.random.default_rng(0), 3, 480, 360)[:2]
    rng = np.random.default_rng(1)
    lab = make_lab(rng)
    shots = []
    for camera in cameras:
        shots.append(folder / camera.name / "table.png")
        shots[-1].parent.mkdir()
        cv2.imwrite(str(shots[-1]), render_table_view(camera, lab, rng))
    return cameras, shots


def test_table_shots_check_an_import_and_fail_perturbed_extrinsics(tmp_path, twin_shots):
    cameras, shots = twin_shots
    export_anipose_toml(cameras, tmp_path / "calibration.toml")
    loaded, payload = run_import(tmp_path, tmp_path / "calibration.toml", "table", shots=shots,
                                 names=["cam0", "cam1"])
    assert_same_cameras(loaded, cameras)
    checks = payload["import_checks"]
    assert [c["camera"] for c in checks] == ["cam0", "cam1"] and "table mat" in checks[0]["points"]
    assert max(c["rms_px"] for c in checks) < 0.3  # the twin's true cameras: rendering and detection only
    # the same file with cam1 shifted 3 cm sideways: the mat's corners move ~3 px at 4 m
    shifted = Camera("cam1", cameras[1].K, cameras[1].dist, cameras[1].R, cameras[1].t + [0.03, 0.0, 0.0],
                     480, 360)
    export_anipose_toml([cameras[0], shifted], tmp_path / "calibration.toml")
    message = (r"cam1: the calibration reprojects the table mat's \d+ corners in .*cam1/table\.png at "
               r"\d\.\d+ px RMS, over the 1\.20 px limit")
    with pytest.raises(CalibrationError, match=message):
        run_import(tmp_path, tmp_path / "calibration.toml", "table", shots=shots, names=["cam0", "cam1"])


@pytest.mark.parametrize(("units", "world", "names", "message"), [
    (None, "table", NAMES, r"config perception\.calibration_import_units is required"),
    ("m", None, NAMES, r"config perception\.calibration_import_world must say how the import's world"),
    ("m", {"T_table_from_world": np.eye(3).tolist()}, NAMES, r"T_table_from_world must be a 4x4 rigid"),
    ("m", {"table_points": [{"xyz_m": [0, 0, 0], "pixels": {"cam9": [1, 2]}}]}, NAMES,
     r"table_points\[0\]: pixels of camera 'cam9' must be \[u, v\] px of one of the cameras"),
    ("m", {"table_points": [{"xyz_m": [0, 0, 0], "pixels": {"cam0": [1, 2]}}] * 3}, NAMES,
     r"table_points need >= 3 points not on one line, one camera seeing >= 3"),
    ("m", "table", ["cam0", "left"], r"no camera\(s\) \['left'\]; the file names \['cam0', 'cam1', 'cam2', "
                                     r"'cam3'\]"),
])
def test_import_config_errors_name_the_key(tmp_path, units, world, names, message):
    export_anipose_toml(random_cameras(np.random.default_rng(12)), tmp_path / "calibration.toml")
    with pytest.raises(CalibrationError, match=message):
        run_import(tmp_path, tmp_path / "calibration.toml", world, units=units, names=names)


def renamed(cameras: list[Camera], names: list[str]) -> list[Camera]:
    return [Camera(n, c.K, c.dist, c.R, c.t, c.width, c.height) for c, n in zip(cameras, names, strict=True)]


FILE_NAMES = ["cam_01", "cam_02", "cam_03", "cam_04"]  # as a markerless-capture tool names them


def test_a_name_map_serves_a_file_naming_the_cameras_otherwise(tmp_path):
    cameras = random_cameras(np.random.default_rng(14))
    export_anipose_toml(renamed(cameras, FILE_NAMES), tmp_path / "calibration.toml")
    name_map = {"cam_02": "cam1", "cam_01": "cam0", "cam_04": "cam3", "cam_03": "cam2"}
    loaded, _ = run_import(tmp_path, tmp_path / "calibration.toml", "table", name_map=name_map)
    assert_same_cameras(loaded, cameras)
    # cameras named as the file does need no map; a map may rename some only
    loaded, _ = run_import(tmp_path, tmp_path / "calibration.toml", "table", names=["cam_03", "left"],
                           name_map={"cam_01": "left"})
    assert_same_cameras(loaded, renamed([cameras[2], cameras[0]], ["cam_03", "left"]))


@pytest.mark.parametrize(("name_map", "message"), [
    ({}, r"no camera\(s\) \['cam0', 'cam1', 'cam2', 'cam3'\]; the file names \['cam_01', 'cam_02', "
         r"'cam_03', 'cam_04'\], the config's cameras are \['cam0', 'cam1', 'cam2', 'cam3'\]: map the file's "
         r"names to the config's with config perception\.calibration_import_names, e\.g\. \{cam_01: cam0, "
         r"cam_02: cam1, cam_03: cam2, cam_04: cam3\}"),
    ({"cam_01": "cam0", "cam_02": "cam1", "cam_03": "cam2"},
     r"no camera\(s\) \['cam3'\]; the file names .* \(renamed by config "
     r"perception\.calibration_import_names: .*\), the config's cameras are .* e\.g\. \{cam_04: cam3\}"),
    ({"cam_1": "cam0"}, r"config perception\.calibration_import_names maps \['cam_1'\], which the file does "
                        r"not name; the file names \['cam_01', 'cam_02', 'cam_03', 'cam_04'\]"),
    ({"cam_01": "cam0", "cam_02": "cam0"}, r"gives two of the file's cameras .* one name"),
])
def test_an_unknown_camera_names_both_sides_and_suggests_the_map(tmp_path, name_map, message):
    export_anipose_toml(renamed(random_cameras(np.random.default_rng(15)), FILE_NAMES), tmp_path / "c.toml")
    with pytest.raises(CalibrationError, match=message):
        run_import(tmp_path, tmp_path / "c.toml", "table", name_map=name_map)


def test_optitrack_entries_with_and_without_optitrack():
    T_table_from_optitrack = make_transform(Rotation.random(random_state=13).as_matrix(), [0.2, -0.1, 0.9])
    markers = apply_transform(np.linalg.inv(T_table_from_optitrack), TABLE_MARKERS)
    poses = {f"table_marker_{i}": pd.DataFrame([dict(zip("xyz", m, strict=True))] * 3)
             for i, m in enumerate(markers)}
    record = optitrack_record(poses)
    assert record["optitrack_fit_rms_m"] < 1e-12
    np.testing.assert_allclose(table_from_optitrack(record, "c.json"), T_table_from_optitrack, atol=1e-12)
    none = optitrack_record(None)
    assert none["T_table_from_optitrack"] is None and none["optitrack_fit_rms_m"] is None
    with pytest.raises(CalibrationError, match=r"c\.json: no OptiTrack-to-table transform: the lab has no "
                                               r"OptiTrack recording"):
        table_from_optitrack(none, "c.json")
