"""Calibration for a lab without the table mat: a board lying at a known pose on the table or the floor, or
listed scene points, place the cameras; views in any image format OpenCV reads. Board views are rendered
by the twin's board renderer through the rig's distorted lenses (over a plain background, which is all
the board detector looks at), scene points projected with sub-pixel noise."""

import json
import logging

import cv2
import numpy as np
import pandas as pd
import pytest
import yaml
from scipy.spatial.transform import Rotation
from test_calibration_board import render_charuco_view
from workflow_util import ROOT

from pingpong.common.camera import Camera
from pingpong.common.config import validate_config
from pingpong.common.patterns import CHECKERBOARD, Checkerboard
from pingpong.common.script import Named, StageContext
from pingpong.io.calibration_files import CaptureLayoutError, extrinsics_shot, intrinsics_views
from pingpong.perception.calibration import (
    CalibrationError,
    Charuco,
    IntrinsicsSetup,
    ScenePoints,
    WorldBoard,
    _checkerboard_from_its_origin,
    calibrate_intrinsics,
    extrinsics_from_board,
    extrinsics_from_points,
    extrinsics_method,
    find_board,
    read_gray,
    world_board,
)
from pingpong.stages import calibration as stage
from pingpong.twin.calibration_images import checkerboard_poses, render_checkerboard_view
from pingpong.twin.render import Background, pixel_ray_map, subpixel_rays
from pingpong.twin.rig import make_rig

W, H = 960, 720
BOARD = Checkerboard(7, 4, 0.12, margin=0.06)  # 1.08 x 0.72 m with its margin: a floor or table board
BOARD_SPEC = {"type": "checkerboard", "inner_corners": [7, 4], "square_m": 0.12}
TURN = 0.5  # rad about the world's up, for the board on the floor
ON_TABLE = {"type": "board", "origin_m": [-0.36, 1.0, 0.0], "x_axis": [1, 0, 0], "y_axis": [0, -1, 0]}
ON_FLOOR = {"type": "board", "origin_m": [1.0, -0.6, -0.76], "x_axis": [np.cos(TURN), np.sin(TURN), 0.0],
            "y_axis": [np.sin(TURN), -np.cos(TURN), 0.0]}  # face up beside the table, turned by 0.5 rad
# named points of the twin's lab, table frame (m): the table's corners, the net posts' tops, floor marks
SCENE = {"corner_ne": [0.7625, 1.37, 0.0], "corner_nw": [-0.7625, 1.37, 0.0],
         "corner_sw": [-0.7625, -1.37, 0.0], "corner_se": [0.7625, -1.37, 0.0],
         "post_e": [0.9144, 0.0, 0.1525], "post_w": [-0.9144, 0.0, 0.1525],
         "floor_a": [1.5, 2.0, -0.76], "floor_b": [-1.5, -2.0, -0.76]}
CENTRE_TOL_M, ANGLE_TOL_DEG = 0.02, 0.2  # a camera 4-5 m away placed within these


@pytest.fixture(scope="module")
def rig() -> list[Camera]:
    return make_rig(np.random.default_rng(0), 3, W, H)


def plain_background(camera: Camera, rng: np.random.Generator, grey: int = 110) -> Background:
    """A grey scene with the twin's sensor noise (sigma 2 grey levels), for render_checkerboard_view."""
    noise = rng.normal(0.0, 2.0, 2 * camera.width * camera.height * 3)
    return Background(np.full((camera.height, camera.width, 3), grey, np.uint8), pixel_ray_map(camera), None,
                      None, np.clip(noise, 0, 255).round().astype(np.uint8),
                      np.clip(-noise, 0, 255).round().astype(np.uint8))


def board_shot(camera: Camera, spec: dict, rng: np.random.Generator,
               board: Checkerboard = BOARD) -> np.ndarray:
    """The checkerboard lying at the config's pose, as `camera` sees it (BGR)."""
    T = world_board(spec, board).T_world_from_board
    return render_checkerboard_view(camera, plain_background(camera, rng), camera.R @ T[:3, :3],
                                    camera.R @ T[:3, 3] + camera.t, rng, board)


def pose_error(R: np.ndarray, t: np.ndarray, camera: Camera) -> tuple[float, float]:
    """(centre error m, rotation error deg) of a world->camera pose against the camera's."""
    angle = np.degrees(np.linalg.norm(Rotation.from_matrix(R @ camera.R.T).as_rotvec()))
    return float(np.linalg.norm(-R.T @ t - camera.center)), float(angle)


@pytest.mark.parametrize("spec", [ON_TABLE, ON_FLOOR], ids=["on_the_table", "on_the_floor"])
def test_a_board_lying_at_a_known_pose_places_every_camera(rig, spec, tmp_path):
    rng = np.random.default_rng(3)
    for camera in rig:  # three cameras, one of them across the net: the board seen from both ends
        path = tmp_path / f"{camera.name}.png"
        cv2.imwrite(str(path), board_shot(camera, spec, rng))
        T_world_from_board = world_board(spec, BOARD).T_world_from_board
        extr = extrinsics_from_board(path, camera.K, camera.dist, BOARD, T_world_from_board)
        centre, angle = pose_error(extr["R"], extr["t"], camera)
        assert centre < CENTRE_TOL_M and angle < ANGLE_TOL_DEG, (camera.name, centre, angle)
        assert extr["rms_px"] < 0.3 and extr["report"] == {"board_corners": 28}


@pytest.mark.parametrize("order", ["as_found", "turned", "rows_flipped", "columns_flipped"])
def test_the_checkerboard_origin_is_found_whichever_corner_the_detector_starts_from(rig, order, tmp_path):
    camera = rig[2]
    image = board_shot(camera, ON_TABLE, np.random.default_rng(4))
    gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    obj, corners = find_board(gray, BOARD)
    grid = np.arange(len(corners)).reshape(BOARD.inner_rows, BOARD.inner_cols)
    grid = {"as_found": grid, "turned": grid[::-1, ::-1], "rows_flipped": grid[::-1],
            "columns_flipped": grid[:, ::-1]}[order]
    ordered = _checkerboard_from_its_origin(gray, obj, corners[grid.ravel()], BOARD)
    T = world_board(ON_TABLE, BOARD).T_world_from_board
    truth = camera.project(obj.astype(float) @ T[:3, :3].T + T[:3, 3])
    assert np.abs(ordered - truth).max() < 0.5  # px: every corner where the board order puts it


@pytest.mark.parametrize(("board", "spec", "message"), [
    (Checkerboard(6, 6, 0.1), ON_TABLE, r"the 6x6-inner-corner checkerboard .* looks the same turned by 180"),
    (Checkerboard(7, 5, 0.1), ON_TABLE, r"the 7x5-inner-corner checkerboard .* looks the same turned by 180"),
    (BOARD, {**ON_TABLE, "y_axis": [0.1, -1, 0]},
     r"x_axis and y_axis must be perpendicular \(within 1 deg\), they are 84\.3 deg apart"),
    (BOARD, {**ON_TABLE, "x_axis": [0, 0, 0]}, r"x_axis and y_axis must be non-zero directions"),
])
def test_an_unusable_world_board_is_refused(board, spec, message):
    with pytest.raises(CalibrationError, match=r"config perception\.calibration_extrinsics: " + message):
        world_board(spec, board)


def test_a_charuco_board_on_the_table_places_the_cameras(rig, tmp_path):
    board = Charuco(7, 5, 0.2, 0.15)  # a 1.4 x 1.0 m mat on the near half; found by the two near cameras
    spec = {**ON_TABLE, "origin_m": [-0.7, 1.2, 0.0],
            "board": {"type": "charuco", "squares": [7, 5], "square_m": 0.2, "marker_m": 0.15}}
    method = extrinsics_method(spec, BOARD_SPEC)
    assert isinstance(method, WorldBoard) and method.board == board and method.frame == "table"
    T = method.T_world_from_board
    for camera in rig[:2]:
        rays = subpixel_rays(pixel_ray_map(camera), 0, 0, W, H, 2)
        path = tmp_path / f"{camera.name}.bmp"
        R, t = camera.R @ T[:3, :3], camera.R @ T[:3, 3] + camera.t  # board -> camera
        cv2.imwrite(str(path), render_charuco_view(board, rays, R, t, ss=2))
        extr = method.place(camera.name, path, camera.K, camera.dist)
        centre, angle = pose_error(extr["R"], extr["t"], camera)
        assert centre < CENTRE_TOL_M and angle < ANGLE_TOL_DEG, (camera.name, centre, angle)


def scene_pixels(cameras: list[Camera], rng: np.random.Generator, sigma: float = 0.3) -> dict:
    """Each camera's pixels of the SCENE points (clicked to within sigma px)."""
    xyz = np.array(list(SCENE.values()))
    return {c.name: {n: (uv + rng.normal(0, sigma, 2)).tolist() for n, uv in zip(SCENE, c.project(xyz),
                                                                                   strict=True)}
            for c in cameras}


def test_scene_points_place_every_camera(rig):
    pixels = scene_pixels(rig, np.random.default_rng(5))
    method = extrinsics_method({"type": "points", "points": SCENE, "pixels": pixels}, BOARD_SPEC)
    assert isinstance(method, ScenePoints) and method.shot is None
    for camera in rig:
        extr = method.place(camera.name, None, camera.K, camera.dist)
        centre, angle = pose_error(extr["R"], extr["t"], camera)
        assert centre < CENTRE_TOL_M and angle < ANGLE_TOL_DEG, (camera.name, centre, angle)
        assert extr["rms_px"] < 0.6 and extr["report"]["scene_points"] == len(SCENE)


def test_too_few_or_collinear_scene_points_name_the_camera(rig):
    camera = rig[0]
    xyz = np.array([SCENE[n] for n in ("corner_ne", "corner_nw", "corner_sw")])
    message = (r"cam0: config perception\.calibration_extrinsics lists 3 scene points seen by this camera "
               r"\(a, b, c\); at least 4, not on one line")
    with pytest.raises(CalibrationError, match=message):
        extrinsics_from_points("cam0", xyz, camera.project(xyz), ["a", "b", "c"], camera.K, camera.dist,
                               "config perception.calibration_extrinsics")
    line = np.array([[x, 0.0, 0.0] for x in (-1.0, -0.5, 0.5, 1.0)])
    with pytest.raises(CalibrationError, match=r"cam0: f\.yaml lists 4 scene points .* not on one line"):
        extrinsics_from_points("cam0", line, camera.project(line), list("abcd"), camera.K, camera.dist,
                               "f.yaml")


@pytest.mark.parametrize(("listed", "message"), [
    ({"points": {"a": [0, 0]}, "pixels": {"cam0": {}}}, r"point 'a' must be \[x, y, z\] in m"),
    ({"points": {"a": [0, 0, 0]}, "pixels": {"cam0": {"b": [1, 2]}}},
     r"camera 'cam0' sees point 'b', which is not among the points \['a'\]"),
    ({"points": {"a": [0, 0, 0]}, "pixels": {"cam0": {"a": [1]}}},
     r"pixel of point 'a' in camera 'cam0' must be \[u, v\] px"),
    ({"points": {"a": [0, 0, 0]}}, r"expected points: \{name: \[x, y, z\] \(m\)\} and pixels"),
])
def test_malformed_scene_points_name_what_is_wrong(listed, message):
    with pytest.raises(CalibrationError, match=r"config perception\.calibration_extrinsics: " + message):
        extrinsics_method({"type": "points", **listed}, BOARD_SPEC)


# --- the stage, on one camera's views saved as .png and as .jpg ------------------------------------------

@pytest.fixture(scope="module")
def views(rig, tmp_path_factory):
    """cam0's hand-held CHECKERBOARD views in png/cam0/ and (JPEG, quality 95) in jpg/cam0/, each with the
    floor board's extrinsics shot."""
    root = tmp_path_factory.mktemp("views")
    camera, rng = rig[0], np.random.default_rng(6)
    background = plain_background(camera, rng, grey=90)
    for i, (R, t) in enumerate(checkerboard_poses(camera, 10, rng)):
        image = render_checkerboard_view(camera, background, R, t, rng)
        (root / "png/cam0").mkdir(parents=True, exist_ok=True)
        (root / "jpg/cam0").mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(root / f"png/cam0/intrinsics_{i:02d}.png"), image)
        cv2.imwrite(str(root / f"jpg/cam0/intrinsics_{i:02d}.JPG"), image, [cv2.IMWRITE_JPEG_QUALITY, 95])
    shot = board_shot(camera, ON_FLOOR, rng)
    cv2.imwrite(str(root / "png/cam0/extrinsics.png"), shot)
    cv2.imwrite(str(root / "jpg/cam0/extrinsics.jpeg"), shot, [cv2.IMWRITE_JPEG_QUALITY, 95])
    return root


def test_jpg_views_give_the_intrinsics_of_the_png_views(views, rig):
    setup = IntrinsicsSetup(CHECKERBOARD, fit_k3=False)
    png = calibrate_intrinsics(intrinsics_views(views / "png/cam0"), setup)
    jpg = calibrate_intrinsics(intrinsics_views(views / "jpg/cam0"), setup)
    assert [p.endswith(".JPG") for p in jpg["views"]] == [True] * len(png["views"]) == [True] * 10
    np.testing.assert_allclose(np.diag(jpg["K"])[:2], np.diag(png["K"])[:2], rtol=0.003)
    np.testing.assert_allclose(jpg["K"][:2, 2], png["K"][:2, 2], atol=1.0)  # px
    np.testing.assert_allclose(jpg["dist"][:2], png["dist"][:2], atol=0.01)
    np.testing.assert_allclose(np.diag(jpg["K"])[:2], np.diag(rig[0].K)[:2], rtol=0.01)


def stage_params(folder, extrinsics, max_rms_share: float = 0.002) -> dict:
    return {"cameras": ["cam0"], "folders": [str(folder)], "import_units": None, "import_world": None,
            "import_names": {}, "extrinsics": extrinsics,
            "board": {"type": "checkerboard", "inner_corners": [9, 6], "square_m": 0.04}, "fit_k3": None,
            "source": "lab", "max_rms_share": max_rms_share, "frame_crop": {}, "strict": False,
            "take_start_ns": None, "code": ""}


def run_stage(tmp_path, folder, extrinsics, inputs=None, **kw) -> tuple[Camera, dict]:
    out = tmp_path / "cameras.json"
    stage.main(StageContext("calibration", Named(inputs or {}), Named(cameras=str(out)),
                            stage_params(folder, extrinsics, **kw), None))
    payload = json.loads(out.read_text())
    return Camera.from_dict(payload["cameras"][0]), payload


def test_the_stage_places_a_camera_by_the_board_on_the_floor_from_jpgs(views, rig, tmp_path):
    camera, payload = run_stage(tmp_path, views / "jpg/cam0", {**ON_FLOOR, "board": BOARD_SPEC})
    centre, angle = pose_error(camera.R, camera.t, rig[0])
    assert centre < CENTRE_TOL_M and angle < ANGLE_TOL_DEG
    assert payload["world_frame"] == "table" and payload["reports"][0]["board_corners"] == 28


@pytest.mark.parametrize("kind", ["csv", "yaml", "config"])
def test_the_stage_places_a_camera_by_scene_points_in_the_lab_frame(views, rig, tmp_path, caplog, kind):
    pixels = scene_pixels(rig[:1], np.random.default_rng(7))
    T_lab_from_table = np.eye(4)
    T_lab_from_table[:3, :3] = Rotation.from_euler("z", 30, degrees=True).as_matrix()
    T_lab_from_table[:3, 3] = [2.0, -1.0, 0.76]  # a lab frame: floor at z = 0, origin off the table
    lab_xyz = {n: (T_lab_from_table[:3, :3] @ p + T_lab_from_table[:3, 3]).tolist() for n, p in SCENE.items()}
    spec, inputs = {"type": "points", "frame": "lab", "file": f"points.{kind}"}, {}
    path = tmp_path / spec["file"]
    if kind == "csv":
        rows = [{"point": n, "x_m": x, "y_m": y, "z_m": z, "cam0_u": pixels["cam0"][n][0],
                 "cam0_v": pixels["cam0"][n][1]} for n, (x, y, z) in lab_xyz.items()]
        rows[0].update(cam0_u=None, cam0_v=None)  # corner_ne not seen
        pd.DataFrame(rows).to_csv(path, index=False)
    elif kind == "yaml":
        path.write_text(yaml.safe_dump({"points": lab_xyz, "pixels": pixels}))
    else:
        spec = {"type": "points", "frame": "lab", "points": lab_xyz, "pixels": pixels}
    if kind != "config":
        inputs = {"scene_points": str(path)}
    with caplog.at_level(logging.INFO, logger="pingpong.perception.calibration"):
        camera, payload = run_stage(tmp_path, views / "png/cam0", spec, inputs)
    truth = rig[0]
    R_truth = truth.R @ T_lab_from_table[:3, :3].T
    in_lab = Camera("cam0", truth.K, truth.dist, R_truth, truth.t - R_truth @ T_lab_from_table[:3, 3], W, H)
    centre, angle = pose_error(camera.R, camera.t, in_lab)
    assert centre < CENTRE_TOL_M and angle < ANGLE_TOL_DEG
    assert payload["world_frame"] == "lab" and "world frame: the lab's own" in caplog.text
    assert payload["reports"][0]["scene_points"] == (7 if kind == "csv" else 8)


def test_a_mislabelled_scene_point_fails_naming_the_camera_and_the_point(views, rig, tmp_path):
    pixels = scene_pixels(rig[:1], np.random.default_rng(8))
    seen = pixels["cam0"]
    seen["post_e"], seen["floor_a"] = seen["floor_a"], seen["post_e"]  # two labels swapped
    message = (r"cam0: the calibration reprojects its board views \(0\.\d+ px\) and the listed scene points "
               r"\(\d+\.\d+ px; the worst point (post_e|floor_a) at \d+\.\d+ px\) at \d+\.\d+ px RMS, "
               r"over the 2\.40 px limit")
    with pytest.raises(CalibrationError, match=message):
        run_stage(tmp_path, views / "png/cam0", {"type": "points", "points": SCENE, "pixels": pixels})


def test_two_extrinsics_shots_of_one_camera_are_an_error_naming_them(views, tmp_path):
    folder = tmp_path / "cam0"
    folder.mkdir()
    for name in ("extrinsics.png", "extrinsics.tif", "extrinsics.old.png", "table.png"):
        (folder / name).write_bytes(b"")
    with pytest.raises(CaptureLayoutError, match=r"cam0: several extrinsics shots \['extrinsics\.png', "
                                                 r"'extrinsics\.tif'\]: keep one extrinsics\.\{png,jpg"):
        extrinsics_shot(folder, "extrinsics")
    assert extrinsics_shot(folder, "table") == folder / "table.png"
    assert read_gray(views / "jpg/cam0/extrinsics.jpeg").shape == (H, W)


# the lab section's examples (README): each validates against the schema and is what the stage runs
EXAMPLES = """
board_on_the_floor:
  perception:
    calibration_board: {type: charuco, squares: [7, 5], square_m: 0.2, marker_m: 0.15}
    calibration_extrinsics:
      type: board
      origin_m: [-0.7, 1.2, 0.0]
      x_axis: [1, 0, 0]
      y_axis: [0, -1, 0]
scene_points:
  perception:
    calibration_extrinsics:
      type: points
      frame: lab
      points: {door_left: [0.0, 0.0, 0.0], door_right: [0.9, 0.0, 0.0], pillar: [3.2, 4.1, 0.0],
               pillar_top: [3.2, 4.1, 2.5], desk: [1.0, 3.0, 0.75]}
      pixels:
        cam_01: {door_left: [412.5, 903.0], door_right: [690.1, 911.4], pillar: [1502.3, 640.8],
                 pillar_top: [1498.7, 122.6]}
        cam_02: {door_left: [233.0, 700.2], pillar: [1320.4, 560.0], pillar_top: [1311.9, 90.5],
                 desk: [800.0, 610.3]}
scene_points_file:
  perception:
    calibration_extrinsics: {type: points, file: raw/calibration/scene_points.csv, frame: lab}
"""


@pytest.mark.parametrize("name", ["board_on_the_floor", "scene_points", "scene_points_file"])
def test_the_readme_examples_validate_and_parse(name, tmp_path):
    config = validate_config(yaml.safe_load(EXAMPLES)[name], ROOT / "config/schema.yaml")["perception"]
    points_file = None
    if name == "scene_points_file":
        points_file = tmp_path / "scene_points.csv"
        points_file.write_text("point,x_m,y_m,z_m,cam_01_u,cam_01_v\n" + "".join(
            f"{n},{x},{y},{z},{u},{v}\n" for n, (x, y, z), (u, v) in
            zip("abcd", [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)], [(1, 2), (3, 4), (5, 6), (7, 8)],
                strict=True)))
    method = extrinsics_method(config["calibration_extrinsics"], config["calibration_board"], points_file)
    assert method.frame == ("table" if name == "board_on_the_floor" else "lab")
    if name == "board_on_the_floor":
        assert method.board == Charuco(7, 5, 0.2, 0.15) and method.shot == "extrinsics"
    else:
        assert method.shot is None and len(method.pixels["cam_01"]) == 4
