"""The intrinsics board and lens model from the config: a lab's own checkerboard or ChArUco board, k3 fixed
for labs, a clear error naming the board when the views show another, and the fit run by the stage."""

import json

import cv2
import numpy as np
import pytest

from pingpong.common.atomic import write_bytes_atomic
from pingpong.common.camera import Camera
from pingpong.common.patterns import CHECKERBOARD, Checkerboard
from pingpong.common.script import Named, StageContext
from pingpong.perception.calibration import (
    CalibrationError,
    Charuco,
    IntrinsicsSetup,
    calibrate_intrinsics,
    camera_folder_paths,
    describe_board,
    intrinsics_board,
    intrinsics_setup,
)
from pingpong.stages import calibration as stage
from pingpong.twin.calibration_images import checkerboard_poses, render_checkerboard_view, render_table_view
from pingpong.twin.render import average_subsamples, make_lab, pixel_ray_map, render_background, subpixel_rays
from pingpong.twin.rig import make_rig

LAB_BOARD = Checkerboard(7, 5, 0.05)  # not the default 9x6, 40 mm
LAB_SPEC = {"type": "checkerboard", "inner_corners": [7, 5], "square_m": 0.05}
N_VIEWS = 8


@pytest.fixture(scope="module")
def lab_camera():
    return make_rig(np.random.default_rng(0), 3, 480, 360)[0]  # at 60 deg: it sees the mat well


@pytest.fixture(scope="module")
def lab_folder(tmp_path_factory, lab_camera):
    """cam0/intrinsics_*.png of the 7x5 board and cam0/table.png, rendered by the twin's code."""
    folder = tmp_path_factory.mktemp("lab_calibration") / "cam0"
    rng = np.random.default_rng(1)
    lab = make_lab(rng)
    background = render_background(lab_camera, lab, rng)
    for i, (R, t) in enumerate(checkerboard_poses(lab_camera, N_VIEWS, rng, LAB_BOARD)):
        image = render_checkerboard_view(lab_camera, background, R, t, rng, LAB_BOARD)
        write_bytes_atomic(folder / f"intrinsics_{i:02d}.png", cv2.imencode(".png", image)[1].tobytes())
    table = render_table_view(lab_camera, lab, rng, ray_map=background.ray_map)
    write_bytes_atomic(folder / "table.png", cv2.imencode(".png", table)[1].tobytes())
    return folder


def test_boards_from_their_config_description():
    default = {"type": "checkerboard", "inner_corners": [9, 6], "square_m": 0.04}
    assert intrinsics_board(default) == CHECKERBOARD
    assert intrinsics_board(LAB_SPEC) == LAB_BOARD
    charuco = intrinsics_board({"type": "charuco", "squares": [7, 5], "square_m": 0.03, "marker_m": 0.022,
                                "dictionary": "DICT_5X5_100"})
    assert charuco == Charuco(7, 5, 0.03, 0.022, "DICT_5X5_100")
    assert charuco.board().getChessboardSize() == (7, 5)
    assert describe_board(LAB_BOARD) == "7x5-inner-corner checkerboard (square 50 mm)"


CHECKER = {"type": "checkerboard", "inner_corners": [9, 6], "square_m": 0.025}
CHARUCO = {"type": "charuco", "squares": [5, 7], "square_m": 0.03, "marker_m": 0.02}


@pytest.mark.parametrize(("spec", "message"), [
    ({**CHECKER, "square_m": 25}, r"square_m is the square's side in m"),
    ({**CHECKER, "inner_corners": [9]}, r"inner_corners must be \[cols, rows\]"),
    ({"type": "checkerboard", "square_m": 0.025}, r"a checkerboard needs \['inner_corners', 'square_m', "
                                                   r"'type'\]"),
    ({**CHARUCO, "dictionary": "4X4"}, r"dictionary must name a cv2.aruco dictionary"),
    ({**CHARUCO, "marker_m": 0.03}, r"marker_m must be positive"),
    ({"type": "circles"}, r"type must be 'checkerboard' or 'charuco'"),
])
def test_bad_board_descriptions_name_the_config_key(spec, message):
    with pytest.raises(ValueError, match=r"config perception\.calibration_board: " + message):
        intrinsics_board(spec)


def test_a_non_default_checkerboard_calibrates(lab_folder, lab_camera):
    views, _ = camera_folder_paths(lab_folder)
    intr = calibrate_intrinsics(views, IntrinsicsSetup(LAB_BOARD, fit_k3=False))
    assert len(intr["views"]) >= N_VIEWS - 1 and intr["rms_px"] < 0.3
    np.testing.assert_allclose(np.diag(intr["K"])[:2], np.diag(lab_camera.K)[:2], rtol=0.01)
    np.testing.assert_allclose(intr["K"][:2, 2], lab_camera.K[:2, 2], atol=3.0)  # principal point, px


def test_the_wrong_board_names_the_board_the_folder_and_the_files(lab_folder):
    views, _ = camera_folder_paths(lab_folder)
    message = (rf"{lab_folder}: only 0 of {N_VIEWS} views show the 9x6-inner-corner checkerboard "
               r"\(square 40 mm\) \(need 4\); check the board in config perception\.calibration_board\. "
               r"Not found in: intrinsics_00\.png, intrinsics_01\.png")
    with pytest.raises(CalibrationError, match=message):
        calibrate_intrinsics(views)  # the default board


def test_k3_is_fixed_for_labs_and_fitted_when_asked(lab_folder):
    lab = intrinsics_setup(LAB_SPEC, None, "lab")
    assert (lab.fit_k3, lab.flags) == (False, cv2.CALIB_FIX_K3)
    assert intrinsics_setup(LAB_SPEC, None, "twin").fit_k3  # as the twin always calibrated
    asked = intrinsics_setup(LAB_SPEC, True, "lab")
    assert asked.fit_k3 and asked.flags == 0
    views, _ = camera_folder_paths(lab_folder)
    assert calibrate_intrinsics(views, lab)["dist"][4] == 0.0
    assert calibrate_intrinsics(views, asked)["dist"][4] != 0.0


def fit_params(folder, max_rms_share: float = 0.002) -> dict:
    """The stage's params for a lab fitting its one camera cam0 on LAB_BOARD, k3 left to the lab default."""
    return {"cameras": ["cam0"], "folders": [str(folder)], "import_units": None, "import_world": None,
            "import_names": {}, "extrinsics": "table_mat", "board": LAB_SPEC, "fit_k3": None, "source": "lab",
            "max_rms_share": max_rms_share, "frame_crop": {}, "strict": False, "take_start_ns": None,
            "code": ""}


def test_the_stage_fits_a_lab_without_optitrack(lab_folder, lab_camera, tmp_path):
    out = tmp_path / "cameras.json"
    inputs = Named(shots=[str(lab_folder / "table.png")])  # and no optitrack
    stage.main(StageContext("calibration", inputs, Named(cameras=str(out)), fit_params(lab_folder), None))
    payload = json.loads(out.read_text())
    camera = Camera.from_dict(payload["cameras"][0])
    assert camera.dist[4] == 0.0  # k3 fixed for the lab
    assert np.linalg.norm(camera.center - lab_camera.center) < 0.02  # m
    assert payload["T_table_from_optitrack"] is None and payload["optitrack_fit_rms_m"] is None
    assert "no OptiTrack" in payload["T_table_from_optitrack_reason"]
    assert payload["reports"][0]["extrinsics_rms_px"] < 0.3


def test_the_stage_fails_a_fit_over_the_reprojection_limit(lab_folder, tmp_path):
    ctx = StageContext("calibration", Named(), Named(cameras=str(tmp_path / "c.json")),
                       fit_params(lab_folder, max_rms_share=1e-5), None)
    with pytest.raises(CalibrationError, match=r"cam0: the calibration reprojects .* px RMS, over the "
                                               r"0\.01 px limit \(1e-05 of the 480x360 image's diagonal"):
        stage.main(ctx)
    assert not (tmp_path / "c.json").exists()


# --- a ChArUco board, rendered here through a distorted lens ------------------------------------------

def render_charuco_view(board: Charuco, rays: np.ndarray, R: np.ndarray, t: np.ndarray, ss: int = 4,
                        ppm: float = 4000) -> np.ndarray:
    """The board at board-to-camera pose (R, t) over grey, (H, W) uint8: each of the ss x ss subsamples'
    ray (normalised coordinates (H ss, W ss, 2), twin.render.subpixel_rays) traced to the board plane."""
    size = (round(board.squares_x * board.square * ppm), round(board.squares_y * board.square * ppm))
    printed = board.board().generateImage(size).astype(np.float32)
    d = np.concatenate([rays, np.ones(rays.shape[:-1] + (1,))], axis=-1) @ R  # the rays in the board frame
    origin = R.T @ t
    on_board = (origin[2] / d[..., 2])[..., None] * d - origin  # board z = 0, m
    maps = (on_board[..., :2] * ppm - 0.5).astype(np.float32)
    fine = cv2.remap(printed, maps[..., 0], maps[..., 1], cv2.INTER_NEAREST, borderValue=160)
    return np.clip(average_subsamples(fine[..., None], ss)[..., 0] + 0.5, 0, 255).astype(np.uint8)


def test_a_charuco_board_calibrates(tmp_path, lab_camera):
    board = Charuco(7, 5, 0.03, 0.022)
    # poses of a checkerboard of the same squares: its frame starts one square in from the ChArUco's
    proxy = Checkerboard(6, 4, board.square, margin=0.0)
    rays = subpixel_rays(pixel_ray_map(lab_camera), 0, 0, lab_camera.width, lab_camera.height, 4)
    for i, (R, t) in enumerate(checkerboard_poses(lab_camera, N_VIEWS, np.random.default_rng(2), proxy)):
        image = render_charuco_view(board, rays, R, t - R @ [board.square, board.square, 0])
        cv2.imwrite(str(tmp_path / f"intrinsics_{i:02d}.png"), image)
    views = sorted(tmp_path.glob("intrinsics_*.png"))
    intr = calibrate_intrinsics(views, IntrinsicsSetup(board, fit_k3=False))
    assert len(intr["views"]) == N_VIEWS and intr["rms_px"] < 0.5
    # at 480x360 the markers are ~20 px: corners come within 0.1-0.5 px and the focal length within 2 %
    np.testing.assert_allclose(np.diag(intr["K"])[:2], np.diag(lab_camera.K)[:2], rtol=0.025)
    np.testing.assert_allclose(intr["dist"][:2], lab_camera.dist[:2], atol=0.03)
    with pytest.raises(CalibrationError, match=r"views show the 7x5-square ChArUco board \(square 30 mm, "
                                               r"marker 22 mm, DICT_5X5_50\)"):
        calibrate_intrinsics(views, IntrinsicsSetup(Charuco(7, 5, 0.03, 0.022, "DICT_5X5_50")))
