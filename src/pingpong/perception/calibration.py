"""Camera calibration: intrinsics from views of a hand-held board (any image format OpenCV reads), extrinsics
from the ChArUco mat on the table, a board lying at a known pose (floor or table) or listed scene points;
or an imported calibration placed in the table frame. Either is checked by reprojection.

OpenCV does the work (findChessboardCorners + cornerSubPix or CharucoDetector, calibrateCamera,
solvePnP); this module only chains it and reports errors per camera. The calibration rule also fits
the OptiTrack-to-table transform from the table-corner markers (optitrack_to_table) where the lab has
OptiTrack.
"""

import logging
import os
from collections import Counter
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import yaml
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from pingpong.common.artifacts import read_json
from pingpong.common.camera import Camera
from pingpong.common.patterns import (
    CHECKERBOARD,
    TABLE_CHARUCO,
    TABLE_MARKERS,
    Checkerboard,
    TableCharuco,
    table_pattern_object_points,
)
from pingpong.common.rigid import fit_rigid_transform, invert_transform, make_transform
from pingpong.io.calibration_files import (
    BOARD_SHOT,
    FORMATS,
    TABLE_SHOT,
    VIEWS_STEM,
    extrinsics_shot,
    intrinsics_views,
)
from pingpong.io.calibration_import import change_world_frame, read_anipose_toml, read_opencv_calibration
from pingpong.perception.schemas import CAMERAS

log = logging.getLogger(__name__)
SUBPIX = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-4)
OUTLIER_VIEW_FACTOR = 3.0  # a view whose RMS exceeds this many times the median view's is dropped
MIN_VIEWS = 4
MIN_CHARUCO_CORNERS = 6  # per intrinsics view: fewer constrain the view's pose poorly
BOARD_CONFIG = "config perception.calibration_board"
WORLD_CONFIG = "config perception.calibration_import_world"
RMS_CONFIG = "config perception.calibration_max_rms_share"
EXTRINSICS_CONFIG = "config perception.calibration_extrinsics"
NAMES_CONFIG = "config perception.calibration_import_names"
CROP_CONFIG = "config perception.frame_crop"


class CalibrationError(RuntimeError):
    pass


# --- the intrinsics board and lens model --------------------------------------------------------------
# A lab's own board is described here rather than in common.patterns (where the twin's CHECKERBOARD is):
# every twin rule hashes that module, so an edit there would re-render the twin for nothing.

@dataclass(frozen=True)
class Charuco:
    """A hand-held ChArUco intrinsics board: squares_x by squares_y squares, ArUco markers in the white ones.

    Unlike a checkerboard it is found when partly outside the image or occluded, so views can reach the
    image corners. `legacy` is the layout of boards generated before OpenCV 4.6 (it differs when
    squares_y is even).
    """

    squares_x: int
    squares_y: int
    square: float  # m
    marker: float  # m
    dictionary: str = "DICT_4X4_50"  # a cv2.aruco predefined dictionary
    legacy: bool = False

    def board(self) -> cv2.aruco.CharucoBoard:
        dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        board = cv2.aruco.CharucoBoard((self.squares_x, self.squares_y), self.square, self.marker, dictionary)
        board.setLegacyPattern(self.legacy)
        return board


def describe_board(board: Checkerboard | Charuco) -> str:
    """The board as an error message names it, e.g. '9x6-inner-corner checkerboard (square 40 mm)'."""
    if isinstance(board, Checkerboard):
        return (f"{board.inner_cols}x{board.inner_rows}-inner-corner checkerboard "
                f"(square {1e3 * board.square:g} mm)")
    return (f"{board.squares_x}x{board.squares_y}-square ChArUco board (square {1e3 * board.square:g} mm, "
            f"marker {1e3 * board.marker:g} mm, {board.dictionary}{', legacy' if board.legacy else ''})")


BOARD_KEYS = {  # type: (required, optional) keys
    "checkerboard": ({"type", "inner_corners", "square_m"}, set()),
    "charuco": ({"type", "squares", "square_m", "marker_m"}, {"dictionary", "legacy"}),
}


def intrinsics_board(spec: dict) -> Checkerboard | Charuco:
    """The intrinsics board of a config description, lengths in m:
    {type: checkerboard, inner_corners: [cols, rows], square_m} (inner corners as
    cv2.findChessboardCorners counts them: one fewer than the squares) or
    {type: charuco, squares: [x, y], square_m, marker_m, dictionary: DICT_4X4_50, legacy: false}.
    """
    kind = spec.get("type")
    if kind not in BOARD_KEYS:
        raise ValueError(f"{BOARD_CONFIG}: type must be 'checkerboard' or 'charuco', got {kind!r}")
    required, optional = BOARD_KEYS[kind]
    if set(spec) - required - optional or required - set(spec):
        raise ValueError(f"{BOARD_CONFIG}: a {kind} needs {sorted(required)} (optional {sorted(optional)}), "
                         f"got {sorted(spec)}")
    square = spec["square_m"]
    if not 0 < square < 1:  # 25 here is a side in mm
        raise ValueError(f"{BOARD_CONFIG}: square_m is the square's side in m, got {square}")
    if kind == "checkerboard":
        return Checkerboard(*_grid(spec["inner_corners"], "inner_corners"), float(square))
    dictionary, marker = str(spec.get("dictionary", "DICT_4X4_50")), spec["marker_m"]
    if not (dictionary.startswith("DICT_") and hasattr(cv2.aruco, dictionary)):
        raise ValueError(f"{BOARD_CONFIG}: dictionary must name a cv2.aruco dictionary (e.g. DICT_4X4_50), "
                         f"got {dictionary!r}")
    if not 0 < marker < square:
        raise ValueError(f"{BOARD_CONFIG}: marker_m must be positive and below square_m ({square}), "
                         f"got {marker}")
    return Charuco(*_grid(spec["squares"], "squares"), float(square), float(marker), dictionary,
                   bool(spec.get("legacy", False)))


def _grid(grid, key: str) -> tuple[int, int]:
    if not (isinstance(grid, list | tuple) and len(grid) == 2 and all(isinstance(n, int) and n >= 2
                                                                     for n in grid)):
        raise ValueError(f"{BOARD_CONFIG}: {key} must be [cols, rows], two integers >= 2, got {grid!r}")
    return int(grid[0]), int(grid[1])


@dataclass(frozen=True)
class IntrinsicsSetup:
    """The board each camera is shown for its intrinsics, and the lens model fitted to the views."""

    board: Checkerboard | Charuco = CHECKERBOARD
    # k3 (the r^6 term) is pinned only by corners near the image's corners, which a hand-held board
    # rarely reaches: on a lab's cameras a free k3 came out at 12 on one camera and moved the image
    # corners by 350-430 px. Labs fix it at 0 (cv2.CALIB_FIX_K3, intrinsics_setup). The default fits it,
    # as the twin always has: the twin's calibration stays what it was (its k3 comes out within 0.09 of 0).
    fit_k3: bool = True

    @property
    def flags(self) -> int:
        """The cv2.calibrateCamera flags of this lens model."""
        return 0 if self.fit_k3 else cv2.CALIB_FIX_K3


def intrinsics_setup(board: dict, fit_k3: bool | None, source: str) -> IntrinsicsSetup:
    """The setup of the calibration stage's params: board as config perception.calibration_board
    describes it; fit_k3 None fits k3 on the twin only (as before) and fixes it for a lab."""
    return IntrinsicsSetup(intrinsics_board(board), source == "twin" if fit_k3 is None else bool(fit_k3))


def read_gray(path) -> np.ndarray:
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if image is None:
        raise CalibrationError(f"{path}: cannot be decoded as an image")
    return image


def find_checkerboard(gray: np.ndarray, board: Checkerboard = CHECKERBOARD) -> np.ndarray | None:
    """Sub-pixel inner corners (N, 2) of the checkerboard, or None when it is not fully visible."""
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    found, corners = cv2.findChessboardCorners(gray, board.pattern_size, flags=flags)
    if not found:
        return None
    return cv2.cornerSubPix(gray, corners, (5, 5), (-1, -1), SUBPIX).reshape(-1, 2)


def find_board(gray: np.ndarray, board: Checkerboard | Charuco) -> tuple[np.ndarray, np.ndarray] | None:
    """Board-frame points (N, 3) m and their image positions (N, 2) px, float32, or None when not found."""
    if isinstance(board, Checkerboard):
        corners = find_checkerboard(gray, board)
        return None if corners is None else (board.object_points().astype(np.float32),
                                              corners.astype(np.float32))
    cv_board = board.board()
    corners, ids, _, _ = cv2.aruco.CharucoDetector(cv_board).detectBoard(gray)
    if ids is None or len(ids) < MIN_CHARUCO_CORNERS or cv_board.checkCharucoCornersCollinear(ids):
        return None
    return (cv_board.getChessboardCorners()[ids.ravel()].astype(np.float32),
            corners.reshape(-1, 2).astype(np.float32))


def calibrate_intrinsics(paths: list, setup: IntrinsicsSetup = IntrinsicsSetup()) -> dict:
    """K, dist (k1 k2 p1 p2 k3), RMS reprojection error (px) and views used, from views of the board."""
    object_points, image_points, size, used = [], [], None, []
    for path in paths:
        gray = read_gray(path)
        if size is not None and gray.shape[::-1] != size:
            raise CalibrationError(f"{path}: {gray.shape[1]}x{gray.shape[0]} px, the other views {size[0]}x"
                                   f"{size[1]} px: one camera's views must share its resolution")
        size = gray.shape[::-1]
        found = find_board(gray, setup.board)
        if found is None:
            log.warning("%s: no %s found, view skipped", path, describe_board(setup.board))
            continue
        object_points.append(found[0])
        image_points.append(found[1])
        used.append(str(path))
    if len(used) < MIN_VIEWS:
        raise CalibrationError(_unusable_views(paths, used, setup.board))
    rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(object_points, image_points, size, None, None,
                                                     flags=setup.flags)
    # A board seen nearly edge-on gives poorly located corners that pull the whole fit:
    # drop views far worse than the typical one and fit again (once).
    view_rms = np.array([_view_rms(o, i, r, t, K, dist)
                         for o, i, r, t in zip(object_points, image_points, rvecs, tvecs, strict=True)])
    keep = view_rms <= OUTLIER_VIEW_FACTOR * np.median(view_rms)
    if not keep.all() and keep.sum() >= MIN_VIEWS:
        for path in np.array(used)[~keep]:
            log.warning("%s: view reprojects %.2f px RMS (median %.2f), dropped", path,
                        view_rms[used.index(path)], np.median(view_rms))
        object_points = [o for o, k in zip(object_points, keep, strict=True) if k]
        image_points = [i for i, k in zip(image_points, keep, strict=True) if k]
        used = [u for u, k in zip(used, keep, strict=True) if k]
        rms, K, dist, _, _ = cv2.calibrateCamera(object_points, image_points, size, None, None,
                                                 flags=setup.flags)
    return {"K": K, "dist": dist.ravel()[:5], "rms_px": float(rms), "views": used, "size": size}


def _unusable_views(paths: list, used: list, board: Checkerboard | Charuco) -> str:
    folder = Path(os.path.commonpath([str(p) for p in paths])) if paths else Path("?")
    folder = folder.parent if folder.is_file() else folder
    missed = [os.path.relpath(p, folder) for p in paths if str(p) not in used]
    return (f"{folder}: only {len(used)} of {len(paths)} views show the {describe_board(board)} (need "
            f"{MIN_VIEWS}); check the board in {BOARD_CONFIG}. Not found in: {', '.join(missed)}")


def _view_rms(obj, img, rvec, tvec, K, dist) -> float:
    projected, _ = cv2.projectPoints(obj, rvec, tvec, K, dist)
    return float(np.sqrt(np.mean(np.sum((projected.reshape(-1, 2) - img.reshape(-1, 2)) ** 2, axis=1))))


def table_corners(path, pattern: TableCharuco = TABLE_CHARUCO) -> tuple[np.ndarray, np.ndarray]:
    """Table-frame points (N, 3) m of the mat's ChArUco corners seen in a table shot, and their sub-pixel
    image positions (N, 1, 2) px."""
    gray = read_gray(path)
    detector = cv2.aruco.CharucoDetector(pattern.board())
    corners, ids, _, _ = detector.detectBoard(gray)
    if ids is None or len(ids) < 6:
        raise CalibrationError(f"{path}: the table's ChArUco mat is not visible enough "
                               f"({0 if ids is None else len(ids)} corners, need 6)")
    # Far squares are ~10 px deep at 480x360: a larger window would reach into the markers.
    half = max(2, round(2 * gray.shape[1] / 480))
    corners = cv2.cornerSubPix(gray, corners.astype(np.float32), (half, half), (-1, -1), SUBPIX)
    return table_pattern_object_points(ids.ravel(), pattern), corners


def extrinsics_from_table(path, K: np.ndarray, dist: np.ndarray,
                          pattern: TableCharuco = TABLE_CHARUCO) -> dict:
    """World(table)->camera R, t from the ChArUco mat on the table, with its reprojection RMS (px)."""
    obj, corners = table_corners(path, pattern)
    ok, rvec, tvec = cv2.solvePnP(obj, corners, K, dist, flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        raise CalibrationError(f"{path}: solvePnP failed on {len(obj)} ChArUco corners")
    projected, _ = cv2.projectPoints(obj, rvec, tvec, K, dist)
    rms = float(np.sqrt(np.mean(np.sum((projected.reshape(-1, 2) - corners.reshape(-1, 2)) ** 2, axis=1))))
    return {"R": cv2.Rodrigues(rvec)[0], "t": tvec.ravel(), "rms_px": rms, "n_corners": int(len(obj))}


# --- where the cameras stand: the world frame from the table mat, a board at a known pose, or points ---

@dataclass(frozen=True)
class TableMat:
    """The table's ChArUco mat (patterns.TABLE_CHARUCO) in each camera's table.{ext}: the table frame."""

    shot: str = TABLE_SHOT
    frame: str = "table"
    what: str = "the table mat"

    def place(self, name: str, shot, K: np.ndarray, dist: np.ndarray) -> dict:
        extr = extrinsics_from_table(shot, K, dist)
        return {**extr, "report": {"table_corners": extr["n_corners"]}}


@dataclass(frozen=True, eq=False)
class WorldBoard:
    """A board lying flat (on the floor or the table) at a known pose, in each camera's extrinsics.{ext}.

    T_world_from_board maps the board frame (as find_board gives its points: a checkerboard's origin at
    its first inner corner, a ChArUco board's at its corner; z = x cross y, into the board) to the world.
    """

    board: Checkerboard | Charuco
    T_world_from_board: np.ndarray  # 4x4, m
    frame: str  # 'table' (the pose is given in the table frame) or 'lab' (a frame of the lab's own)
    shot: str = BOARD_SHOT
    what: str = "the board at its configured pose"

    def place(self, name: str, shot, K: np.ndarray, dist: np.ndarray) -> dict:
        return extrinsics_from_board(shot, K, dist, self.board, self.T_world_from_board)


@dataclass(frozen=True, eq=False)
class ScenePoints:
    """Named world points (m) and, per camera, the pixels where they are seen: no shot is read."""

    points: dict  # name -> (3,) world position, m
    pixels: dict  # camera -> {name -> (2,) pixel, px}
    frame: str
    where: str  # the config key or file they were listed in, for messages
    shot: None = None
    what: str = "the listed scene points"

    def place(self, name: str, shot, K: np.ndarray, dist: np.ndarray) -> dict:
        seen = self.pixels.get(name, {})
        names = [n for n in seen if n in self.points]
        return extrinsics_from_points(name, np.array([self.points[n] for n in names]).reshape(-1, 3),
                                      np.array([seen[n] for n in names]).reshape(-1, 2), names, K, dist,
                                      self.where)


def log_world_frame(method) -> None:
    if method.frame == "table":
        log.info("world frame: the table frame, placed by %s", method.what)
    else:
        log.warning("world frame: the lab's own (%s gives %s in it, frame: lab); there is no table frame, "
                    "so only stages that need none (pose) apply", EXTRINSICS_CONFIG, method.what)


def _pnp(obj: np.ndarray, img: np.ndarray, K: np.ndarray, dist: np.ndarray, flags: int):
    """solvePnP refined by Levenberg-Marquardt: (R, t, per-point reprojection errors px), or None."""
    obj, img = np.ascontiguousarray(obj, np.float64), np.ascontiguousarray(img, np.float64).reshape(-1, 1, 2)
    ok, rvec, tvec = cv2.solvePnP(obj, img, K, dist, flags=flags)
    if not ok:
        return None
    rvec, tvec = cv2.solvePnPRefineLM(obj, img, K, dist, rvec, tvec)
    projected, _ = cv2.projectPoints(obj, rvec, tvec, K, dist)
    errors = np.linalg.norm(projected.reshape(-1, 2) - img.reshape(-1, 2), axis=1)
    return cv2.Rodrigues(rvec)[0], tvec.ravel(), errors


def _rms(errors: np.ndarray) -> float:
    return float(np.sqrt(np.mean(errors ** 2)))


def extrinsics_from_board(path, K: np.ndarray, dist: np.ndarray, board: Checkerboard | Charuco,
                          T_world_from_board: np.ndarray) -> dict:
    """World->camera R, t from a board lying at a known pose, seen in the shot `path`."""
    gray = read_gray(path)
    found = find_board(gray, board)
    if found is None:
        raise CalibrationError(f"{path}: no {describe_board(board)} found: the extrinsics shot must show "
                               f"the board of {EXTRINSICS_CONFIG} lying at its configured pose")
    obj, img = found
    if isinstance(board, Checkerboard):
        try:
            img = _checkerboard_from_its_origin(gray, obj, img, board)
        except CalibrationError as err:
            raise CalibrationError(f"{path}: {err}") from None
    solved = _pnp(obj, img, K, dist, cv2.SOLVEPNP_IPPE)
    if solved is None:
        raise CalibrationError(f"{path}: solvePnP failed on {len(obj)} board corners")
    R_cb, t_cb, errors = solved
    T_cam_from_world = make_transform(R_cb, t_cb) @ invert_transform(T_world_from_board)
    return {"R": T_cam_from_world[:3, :3], "t": T_cam_from_world[:3, 3], "rms_px": _rms(errors),
            "report": {"board_corners": int(len(obj))}}


def _checkerboard_from_its_origin(gray: np.ndarray, obj: np.ndarray, img: np.ndarray,
                                  board: Checkerboard) -> np.ndarray:
    """The corners in board order, whichever corner cv2.findChessboardCorners started from.

    It may list the grid from any of its four corners. Board order: seen from the printed face, x runs
    along a row and y turned 90 deg clockwise from it (a right-handed frame, z into the board), and the
    square diagonally outside the origin corner is black (the twin's print). Of the four orderings one
    alone has both when one inner-corner count is odd and the other even (world_board refuses others).
    """
    grid = np.arange(len(img)).reshape(board.inner_rows, board.inner_cols)
    blurred = cv2.blur(gray, (3, 3))
    for order in (grid, grid[::-1, ::-1], grid[::-1, :], grid[:, ::-1]):
        candidate = img[order.ravel()]
        dx, dy = candidate[1] - candidate[0], candidate[board.inner_cols] - candidate[0]
        if dx[0] * dy[1] - dx[1] * dy[0] > 0 and _black_outside_origin(blurred, obj, candidate, board):
            return candidate
    raise CalibrationError(f"the {describe_board(board)} shows no black corner square diagonally outside a "
                           f"corner of its grid: is it the configured board?")


def _black_outside_origin(gray: np.ndarray, obj: np.ndarray, img: np.ndarray, board: Checkerboard) -> bool:
    """Whether the square diagonally outside corner 0 is darker than its two neighbours along the edges."""
    H, _ = cv2.findHomography(obj[:, :2].astype(np.float64), img.astype(np.float64))
    probes = np.array([[-0.5, -0.5], [0.5, -0.5], [-0.5, 0.5]]) * board.square
    px = cv2.perspectiveTransform(probes.reshape(-1, 1, 2), H).reshape(-1, 2)
    if not ((px >= 0).all() and (px < np.array(gray.shape[::-1]) - 1).all()):
        raise CalibrationError(f"the {describe_board(board)}'s outer squares lie outside the image: the "
                               f"whole board must be in the extrinsics shot")
    level = gray[np.round(px[:, 1]).astype(int), np.round(px[:, 0]).astype(int)].astype(float)
    return bool(level[0] < level[1:].min())


def world_board(spec: dict, board: Checkerboard | Charuco) -> WorldBoard:
    """The WorldBoard of a config {type: board, origin_m, x_axis, y_axis, frame, board}."""
    if isinstance(board, Checkerboard) and (board.inner_cols == board.inner_rows
                                            or (board.inner_cols + board.inner_rows) % 2 == 0):
        raise CalibrationError(f"{EXTRINSICS_CONFIG}: the {describe_board(board)} looks the same turned by "
                               f"180 deg, so its corners cannot be told apart: lay a checkerboard with an "
                               f"odd and an even number of inner corners (e.g. 9x6), or a ChArUco board")
    x, y = (np.asarray(spec[k], float).reshape(3) for k in ("x_axis", "y_axis"))
    if min(np.linalg.norm(x), np.linalg.norm(y)) < 1e-9:
        raise CalibrationError(f"{EXTRINSICS_CONFIG}: x_axis and y_axis must be non-zero directions")
    x, y = x / np.linalg.norm(x), y / np.linalg.norm(y)
    if abs(x @ y) > np.sin(np.radians(1.0)):
        angle = np.degrees(np.arccos(np.clip(x @ y, -1, 1)))
        raise CalibrationError(f"{EXTRINSICS_CONFIG}: x_axis and y_axis must be perpendicular (within "
                               f"1 deg), they are {angle:.1f} deg apart")
    y = y - (x @ y) * x  # exactly perpendicular
    y /= np.linalg.norm(y)
    R = np.column_stack([x, y, np.cross(x, y)])
    return WorldBoard(board, make_transform(R, np.asarray(spec["origin_m"], float).reshape(3)),
                      spec.get("frame", "table"))


def extrinsics_from_points(name: str, xyz: np.ndarray, pixels: np.ndarray, names: list[str],
                           K: np.ndarray, dist: np.ndarray, where: str) -> dict:
    """World->camera R, t from >= 4 named world points (N, 3) m and their pixels (N, 2) px: SQPnP, then
    Levenberg-Marquardt on every point."""
    if len(xyz) < 4 or np.linalg.matrix_rank(xyz - xyz.mean(axis=0), tol=1e-3) < 2:
        raise CalibrationError(f"{name}: {where} lists {len(xyz)} scene points seen by this camera "
                               f"({', '.join(names) or 'none'}); at least 4, not on one line, are needed")
    solved = _pnp(xyz, pixels, K, dist, cv2.SOLVEPNP_SQPNP)
    if solved is None:
        raise CalibrationError(f"{name}: solvePnP failed on the scene points of {where}")
    R, t, errors = solved
    worst = int(np.argmax(errors))
    log.info("%s: scene points reproject at %.2f px RMS, the worst %s at %.2f px", name, _rms(errors),
             names[worst], errors[worst])
    return {"R": R, "t": t, "rms_px": _rms(errors),
            "report": {"scene_points": len(names), "worst_point": names[worst],
                       "worst_point_px": float(errors[worst])}}


def extrinsics_method(spec, board_spec: dict, points_file=None) -> "TableMat | WorldBoard | ScenePoints":
    """How the stage places the cameras, from config perception.calibration_extrinsics: 'table_mat',
    {type: board, origin_m, x_axis, y_axis, [board], [frame]} (board: the calibration board when absent)
    or {type: points, points: {name: [x, y, z]}, pixels: {camera: {name: [u, v]}}, [frame]} /
    {type: points, file, [frame]} (the file's contents, read from `points_file`, the rule's input)."""
    if spec in (None, "table_mat"):
        return TableMat()
    kind = spec.get("type") if isinstance(spec, dict) else None
    if kind == "board":
        return world_board(spec, intrinsics_board(spec.get("board", board_spec)))
    if kind == "points":
        listed, where = spec, EXTRINSICS_CONFIG
        if "file" in spec:
            if points_file is None:
                raise CalibrationError(f"{EXTRINSICS_CONFIG}: file {spec['file']} is not among the rule's "
                                       f"inputs")
            listed, where = read_scene_points(points_file), str(points_file)
        return scene_points(listed, spec.get("frame", "table"), where)
    raise CalibrationError(f"{EXTRINSICS_CONFIG} must be 'table_mat', {{type: board, ...}} or {{type: "
                           f"points, ...}}; got {spec!r}")


def scene_points(listed: dict, frame: str, where: str) -> ScenePoints:
    """ScenePoints of {points: {name: [x, y, z] m}, pixels: {camera: {name: [u, v] px}}}, checked."""
    points, pixels = listed.get("points"), listed.get("pixels")
    if not (isinstance(points, dict) and points and isinstance(pixels, dict) and pixels):
        raise CalibrationError(f"{where}: expected points: {{name: [x, y, z] (m)}} and pixels: {{camera: "
                               f"{{name: [u, v] (px)}}}}, got {listed!r}")
    xyz = {}
    for name, p in points.items():
        if np.size(p) != 3 or not np.all(np.isfinite(np.asarray(p, float))):
            raise CalibrationError(f"{where}: point {name!r} must be [x, y, z] in m, got {p!r}")
        xyz[str(name)] = np.asarray(p, float).reshape(3)
    uv = {}
    for cam, seen in pixels.items():
        if not isinstance(seen, dict):
            raise CalibrationError(f"{where}: pixels of camera {cam!r} must map point names to [u, v] px")
        for name, q in seen.items():
            if str(name) not in xyz:
                raise CalibrationError(f"{where}: camera {cam!r} sees point {name!r}, which is not among the "
                                       f"points {sorted(xyz)}")
            if np.size(q) != 2 or not np.all(np.isfinite(np.asarray(q, float))):
                raise CalibrationError(f"{where}: pixel of point {name!r} in camera {cam!r} must be [u, v] "
                                       f"px, got {q!r}")
        uv[str(cam)] = {str(n): np.asarray(q, float).reshape(2) for n, q in seen.items()}
    return ScenePoints(xyz, uv, frame, where)


def read_scene_points(path) -> dict:
    """{points, pixels} from a YAML file of that layout, or a CSV with one row per point: point, x_m, y_m,
    z_m, then {camera}_u, {camera}_v column pairs (a cell left empty: not seen by that camera)."""
    path = Path(path)
    if path.suffix.lower() in (".yaml", ".yml"):
        try:
            listed = yaml.safe_load(path.read_text())
        except (OSError, yaml.YAMLError) as err:
            raise CalibrationError(f"{path}: cannot read the scene points ({err})") from None
        return listed if isinstance(listed, dict) else {"points": None, "pixels": None}
    if path.suffix.lower() != ".csv":
        raise CalibrationError(f"{path}: scene points must be a .yaml or .csv file")
    table = pd.read_csv(path)
    cams = [c[:-2] for c in table.columns if c.endswith("_u") and f"{c[:-2]}_v" in table.columns]
    if not {"point", "x_m", "y_m", "z_m"} <= set(table.columns) or not cams:
        raise CalibrationError(f"{path}: expected the columns point, x_m, y_m, z_m and {{camera}}_u, "
                               f"{{camera}}_v per camera; got {list(table.columns)}")
    points = {str(r.point): [r.x_m, r.y_m, r.z_m] for r in table.itertuples()}
    pixels = {cam: {str(p): [u, v] for p, u, v in zip(table["point"], table[f"{cam}_u"], table[f"{cam}_v"],
                                                       strict=True) if pd.notna(u) and pd.notna(v)}
              for cam in cams}
    return {"points": points, "pixels": pixels}


def calibrate_camera(name: str, intrinsics_paths: list, place, setup: IntrinsicsSetup = IntrinsicsSetup()
                     ) -> tuple[Camera, dict]:
    """One camera from its board views and `place` (K, dist -> its extrinsics record: R, t, rms_px and
    the report's entries), and its error report."""
    intr = calibrate_intrinsics(sorted(intrinsics_paths, key=str), setup)
    extr = place(intr["K"], intr["dist"])
    camera = Camera(name, intr["K"], intr["dist"], extr["R"], extr["t"], *intr["size"])
    report = {"name": name, "intrinsics_rms_px": intr["rms_px"], "views_used": len(intr["views"]),
              "extrinsics_rms_px": extr["rms_px"], **extr["report"], "center": camera.center.tolist()}
    log.info("%s: intrinsics RMS %.3f px over %d views, extrinsics RMS %.3f px", name,
             intr["rms_px"], len(intr["views"]), extr["rms_px"])
    return camera, report


def camera_folder_paths(folder, shot_stem: str | None = TABLE_SHOT) -> tuple[list[Path], Path | None]:
    """A camera's intrinsics views `intrinsics_*.{ext}` and its extrinsics shot `{shot_stem}.{ext}` (None
    when shot_stem is None: scene points need none), in any image format OpenCV reads."""
    folder = Path(folder)
    views = intrinsics_views(folder)
    if not views:
        raise CalibrationError(f"{folder}: no intrinsics views {VIEWS_STEM}*.{FORMATS} to calibrate from")
    if shot_stem is None:
        return views, None
    shot = extrinsics_shot(folder, shot_stem)
    if shot is None:
        raise CalibrationError(f"{folder}: no extrinsics shot {shot_stem}.{FORMATS}")
    return views, shot


def fit_calibration(names: list[str], folders: list, setup: IntrinsicsSetup, max_rms_share: float,
                    method=None) -> tuple[list[Camera], list[dict]]:
    """Every camera from its folder's captures, placed in the world by `method` (TableMat, WorldBoard or
    ScenePoints; the table mat by default), and the reports, checked by reprojection."""
    method = method or TableMat()
    log_world_frame(method)
    pairs = []
    for name, folder in zip(names, folders, strict=True):
        views, shot = camera_folder_paths(folder, method.shot)
        pairs.append(calibrate_camera(name, views, partial(method.place, name, shot), setup))
    for camera, report in pairs:
        worst = max(report["intrinsics_rms_px"], report["extrinsics_rms_px"])
        point = (f"; the worst point {report['worst_point']} at {report['worst_point_px']:.2f} px"
                 if "worst_point" in report else "")
        check_rms(camera, worst, f"its board views ({report['intrinsics_rms_px']:.2f} px) and "
                  f"{method.what} ({report['extrinsics_rms_px']:.2f} px{point})", max_rms_share)
    return [c for c, _ in pairs], [r for _, r in pairs]


def rms_limit_px(camera: Camera, max_rms_share: float) -> float:
    """The largest reprojection RMS a calibration may have, px: a share of the image's diagonal, so that one
    setting holds at any resolution (0.002: 1.2 px at 480x360, 4.4 px at 1920x1080)."""
    return max_rms_share * float(np.hypot(camera.width, camera.height))


def check_rms(camera: Camera, rms: float, what: str, max_rms_share: float) -> dict:
    """A reprojection RMS (px) of `what` checked against the camera's limit; its record."""
    limit = rms_limit_px(camera, max_rms_share)
    if not rms <= limit:
        raise CalibrationError(f"{camera.name}: the calibration reprojects {what} at {rms:.2f} px RMS, over "
                               f"the {limit:.2f} px limit ({max_rms_share:g} of the {camera.width}x"
                               f"{camera.height} image's diagonal, {RMS_CONFIG})")
    return {"camera": camera.name, "points": what, "rms_px": rms, "limit_px": limit}


def reprojection_rms(camera: Camera, points: np.ndarray, pixels: np.ndarray) -> float:
    """RMS distance (px) between the projections of table points (N, 3) m and their pixels (N, 2)."""
    error = camera.project(points) - np.asarray(pixels, float).reshape(-1, 2)
    return float(np.sqrt(np.mean(np.sum(error ** 2, axis=1))))


# --- an imported calibration ------------------------------------------------------------------------

def import_calibration(path, units: str | None, world, names: list[str], table_shots: dict,
                       max_rms_share: float, name_map: dict | None = None) -> tuple[list[Camera], list[dict]]:
    """The configured cameras of an imported calibration file, placed in the table frame as `world` says,
    and the records of the reprojection checks they passed (none: unchecked, logged).

    units: the file's length unit (m, cm, mm); world: 'table', 'lab' (no table), {T_table_from_world:
    4x4 (m)} or {table_points: [{xyz_m: [x, y, z], pixels: {camera: [u, v]}}, ...]} (see table_from_world);
    table_shots: camera name -> its table.{ext}, where the lab has them; name_map: {name in the file:
    camera name} for the file's cameras named otherwise than the config's.
    """
    cameras = read_imported_cameras(path, units, names, name_map or {})
    T_table_from_world, observations = table_from_world(world, cameras)
    cameras = change_world_frame(cameras, invert_transform(T_table_from_world))
    if world == "lab":
        log.warning("world frame: the lab's own (%s: lab), the import's kept as it is; there is no table "
                    "frame, so only stages that need none (pose) apply", WORLD_CONFIG)
        table_shots = {}  # the mat's corners are table points: nothing to check them against
    checks = []
    for cam in cameras:
        points, pixels = _observed_by(cam.name, observations)
        if len(points):  # a residual check only: these points placed the rig
            checks.append(check_rms(cam, reprojection_rms(cam, points, pixels),
                                    "the listed table points (which placed the rig)", max_rms_share))
        if cam.name in table_shots:
            points, pixels = table_corners(table_shots[cam.name])
            checks.append(check_rms(cam, reprojection_rms(cam, points, pixels),
                                    f"the table mat's {len(points)} corners in {table_shots[cam.name]}",
                                    max_rms_share))
    if not checks:
        log.warning("%s: the imported calibration is UNCHECKED: no table shots and no table points to "
                    "reproject; its world frame is trusted as %s says (%r)", path, WORLD_CONFIG, world)
    for check in checks:
        log.info("%s: %s reproject at %.2f px RMS (limit %.2f px)", check["camera"], check["points"],
                 check["rms_px"], check["limit_px"])
    return cameras, checks


def read_imported_cameras(path, units: str | None, names: list[str], name_map: dict) -> list[Camera]:
    """The config's cameras `names` read from an imported calibration file in its own world frame (units and
    name_map as import_calibration's); what is wrong with the file, its units or its names is an error."""
    if units is None:
        raise CalibrationError(f"{path}: config perception.calibration_import_units is required with an "
                               f"import: the file's length unit (m, cm or mm), which neither format states")
    reader = read_anipose_toml if str(path).endswith(".toml") else read_opencv_calibration
    return _configured(reader(path, units=units), names, path, name_map)


def _configured(cameras: list[Camera], names: list[str], path, name_map: dict) -> list[Camera]:
    """The config's cameras, in its order, from the file's (renamed by name_map: {file's: config's})."""
    in_file = [c.name for c in cameras]
    unknown = sorted(set(name_map) - set(in_file))
    if unknown:
        raise CalibrationError(f"{path}: {NAMES_CONFIG} maps {unknown}, which the file does not name; the "
                               f"file names {in_file}")
    by_name = {name_map.get(c.name, c.name): replace(c, name=name_map.get(c.name, c.name)) for c in cameras}
    if len(by_name) < len(cameras):
        raise CalibrationError(f"{path}: {NAMES_CONFIG} ({name_map}) gives two of the file's cameras "
                               f"{in_file} one name")
    missing = [n for n in names if n not in by_name]
    if missing:
        example = ", ".join(f"{f}: {c}" for f, c in zip([n for n in in_file if n not in name_map],
                                                        missing, strict=False))
        raise CalibrationError(f"{path}: no camera(s) {missing}; the file names {in_file}"
                               f"{f' (renamed by {NAMES_CONFIG}: {name_map})' if name_map else ''}, the "
                               f"config's cameras are {names}: map the file's names to the config's with "
                               f"{NAMES_CONFIG}, e.g. {{{example}}}")
    return [by_name[n] for n in names]


def _observed_by(name: str, observations: list) -> tuple[np.ndarray, np.ndarray]:
    mine = [(xyz, uv) for cam, xyz, uv in observations if cam == name]
    return np.array([m[0] for m in mine], float).reshape(-1, 3), np.array([m[1] for m in mine], float)


def table_from_world(world, cameras: list[Camera]) -> tuple[np.ndarray, list]:
    """T_table_from_world (4x4, m) of the import's world frame, and the table points' observations
    (camera, xyz (3,) m, pixel (2,) px) where the config lists them."""
    if world in ("table", "lab"):  # lab: the import's frame is the lab's own, kept as it is (no table)
        return np.eye(4), []
    if isinstance(world, dict) and set(world) == {"T_table_from_world"}:
        return _rigid_4x4(world["T_table_from_world"]), []
    if isinstance(world, dict) and set(world) == {"table_points"}:
        observations = _table_points(world["table_points"], [c.name for c in cameras])
        return fit_table_from_world(cameras, observations), observations
    raise CalibrationError(f"{WORLD_CONFIG} must say how the import's world frame relates to the table: "
                           f"'table', 'lab', {{T_table_from_world: 4x4, m}} or {{table_points: [{{xyz_m: "
                           f"[x, y, z], pixels: {{camera: [u, v]}}}}, ...]}}; got {world!r}")


def _rigid_4x4(value) -> np.ndarray:
    T = np.asarray(value, float)
    if T.shape != (4, 4) or not np.allclose(T[3], [0, 0, 0, 1]):
        raise CalibrationError(f"{WORLD_CONFIG}: T_table_from_world must be a 4x4 rigid transform "
                               f"(last row 0 0 0 1), got {np.shape(value)}: {value!r}")
    R = T[:3, :3]
    if not (np.allclose(R.T @ R, np.eye(3), atol=1e-6) and np.linalg.det(R) > 0):
        raise CalibrationError(f"{WORLD_CONFIG}: T_table_from_world's rotation is not orthonormal with "
                               f"determinant +1")
    return T


def _table_points(points, names: list[str]) -> list:
    observations = []
    for i, point in enumerate(points if isinstance(points, list) else [points]):
        where = f"{WORLD_CONFIG}: table_points[{i}]"
        if not (isinstance(point, dict) and set(point) == {"xyz_m", "pixels"} and np.size(point["xyz_m"]) == 3
                and isinstance(point["pixels"], dict) and point["pixels"]):
            raise CalibrationError(f"{where}: expected {{xyz_m: [x, y, z] (table frame, m), pixels: "
                                   f"{{camera: [u, v] (px)}}}}, got {point!r}")
        for cam, uv in point["pixels"].items():
            if cam not in names or np.size(uv) != 2:
                raise CalibrationError(f"{where}: pixels of camera {cam!r} must be [u, v] px of one of the "
                                       f"cameras {names}, got {uv!r}")
            observations.append((cam, np.asarray(point["xyz_m"], float), np.asarray(uv, float)))
    return observations


def fit_table_from_world(cameras: list[Camera], observations: list) -> np.ndarray:
    """T_table_from_world (4x4, m) placing the imported rig on the table from table points' pixels.

    The whole rig moves as one rigid body: 6 unknowns fitted to every camera's pixels, so the import's
    inter-camera geometry is kept, a point seen by one camera counts, and one camera seeing 4 points is
    enough. (Per-camera solvePnP would replace each camera's extrinsics by a 4-point pose; triangulating
    the points would need each in two cameras.) Starts from solvePnP in the camera seeing most points.
    """
    counts = Counter(cam for cam, _, _ in observations)
    xyz = np.array([x for _, x, _ in observations])
    first, n_first = counts.most_common(1)[0] if counts else (None, 0)
    if (n_first < 3 or len(observations) < 4
            or np.linalg.matrix_rank(xyz - xyz.mean(axis=0), tol=1e-3) < 2):
        raise CalibrationError(f"{WORLD_CONFIG}: table_points need >= 3 points not on one line, one camera "
                               f"seeing >= 3 of them and >= 4 pixel positions in all (3 in one camera leave "
                               f"up to 4 poses); got {len(observations)} in cameras {dict(counts)}")
    by_name = {c.name: c for c in cameras}
    start = by_name[first]
    ok, rvec, tvec = cv2.solvePnP(*_observed_by(first, observations), start.K, start.dist,
                                  flags=cv2.SOLVEPNP_SQPNP)
    if not ok:
        raise CalibrationError(f"{WORLD_CONFIG}: solvePnP failed on camera {first}'s table points")
    T_cam_from_table = make_transform(cv2.Rodrigues(rvec)[0], tvec.ravel())
    T0 = invert_transform(make_transform(start.R, start.t)) @ T_cam_from_table  # world from table

    index = [[c.name for c in cameras].index(cam) for cam, _, _ in observations]
    pixels = np.array([uv for _, _, uv in observations])

    def residuals(x: np.ndarray) -> np.ndarray:  # x: T_world_from_table as rotation vector, translation (m)
        moved = change_world_frame(cameras, _transform(x))
        return np.concatenate([moved[c].project(p)[0] - uv
                               for c, p, uv in zip(index, xyz, pixels, strict=True)])

    x0 = np.concatenate([Rotation.from_matrix(T0[:3, :3]).as_rotvec(), T0[:3, 3]])
    return invert_transform(_transform(least_squares(residuals, x0, method="lm").x))


def _transform(x: np.ndarray) -> np.ndarray:
    return make_transform(Rotation.from_rotvec(x[:3]).as_matrix(), x[3:])


# --- recordings of a window of the calibrated image -------------------------------------------------

def crop_to_recorded(cameras: list[Camera], crops: dict) -> list[Camera]:
    """The cameras as their recordings see them: a camera whose recorded frames are the window {x, y, width,
    height} (px) of its calibrated image (crops, config perception.frame_crop: recorded pixel + (x, y) =
    calibrated pixel) gets its principal point moved by -(x, y) and the window's size, so that every stage
    after this one reads the recordings as they are; the others are as calibrated."""
    names = [c.name for c in cameras]
    unknown = sorted(set(crops) - set(names))
    if unknown:
        raise CalibrationError(f"{CROP_CONFIG} names {unknown}, which are not among the cameras {names}")
    return [_cropped(c, crops[c.name]) if c.name in crops else c for c in cameras]


def _cropped(camera: Camera, crop: dict) -> Camera:
    K = camera.K.copy()
    K[:2, 2] -= (crop["x"], crop["y"])
    if not (0 <= K[0, 2] <= crop["width"] and 0 <= K[1, 2] <= crop["height"]):
        raise CalibrationError(f"{camera.name}: {CROP_CONFIG} {crop} puts the principal point at "
                               f"({K[0, 2]:g}, {K[1, 2]:g}) px, outside its {crop['width']} x "
                               f"{crop['height']} px frames")
    log.warning("%s: calibrated at %d x %d px, recorded at %d x %d px from (%d, %d) px of it (%s): principal "
                "point moved to (%.1f, %.1f) px", camera.name, camera.width, camera.height, crop["width"],
                crop["height"], crop["x"], crop["y"], CROP_CONFIG, K[0, 2], K[1, 2])
    return replace(camera, K=K, width=crop["width"], height=crop["height"])


# --- the stored calibration and OptiTrack ---------------------------------------------------------

def load_cameras(path) -> tuple[list[Camera], dict]:
    """The calibrated cameras and the rest of interim/calibration/cameras.json."""
    payload = read_json(path, CAMERAS)
    return [Camera.from_dict(c) for c in payload["cameras"]], payload


def calibrated_camera(path, name: str) -> Camera:
    """The camera `name` of a cameras.json; an error naming the file and its cameras when it has none."""
    cameras, _ = load_cameras(path)
    for camera in cameras:
        if camera.name == name:
            return camera
    raise ValueError(f"{path}: no camera {name!r} (cameras: {', '.join(c.name for c in cameras)}); "
                     "expected one calibrated for each stream")


def table_from_optitrack(calibration: dict, where) -> np.ndarray:
    """T_table_from_optitrack (4x4) of a loaded cameras.json; a clear error where the lab has none."""
    T = calibration.get("T_table_from_optitrack")
    if T is None:
        raise CalibrationError(f"{where}: no OptiTrack-to-table transform: "
                               f"{calibration.get('T_table_from_optitrack_reason', 'none recorded')}")
    return np.asarray(T, float)


NO_OPTITRACK = "the lab has no OptiTrack recording (the calibration rule had no optitrack input)"


def optitrack_record(optitrack: dict[str, pd.DataFrame] | None) -> dict:
    """cameras.json's OptiTrack-to-table entries: the fit on the table markers, or null and the reason."""
    if optitrack is None:
        log.info("no OptiTrack-to-table transform: %s", NO_OPTITRACK)
        return {"T_table_from_optitrack": None, "optitrack_fit_rms_m": None,
                "T_table_from_optitrack_reason": NO_OPTITRACK}
    T, rms = optitrack_to_table(optitrack)
    return {"T_table_from_optitrack": T.tolist(), "optitrack_fit_rms_m": rms}


def fit_optitrack_to_table(
    marker_positions_optitrack: np.ndarray, marker_positions_table: np.ndarray
) -> tuple[np.ndarray, float]:
    """T_table_from_optitrack (4x4) from K >= 3 markers measured in both frames, and its RMS residual (m)."""
    T, rms = fit_rigid_transform(marker_positions_optitrack, marker_positions_table)
    log.info("OptiTrack-to-table fit on %d markers: RMS residual %.2f mm",
             len(marker_positions_table), 1e3 * rms)
    return T, rms


def optitrack_to_table(optitrack: dict[str, pd.DataFrame],
                       marker_prefix: str = "table_marker_") -> tuple[np.ndarray, float]:
    """T_table_from_optitrack from the table-corner markers (each marker's median), and its RMS (m)."""
    names = sorted((b for b in optitrack if b.startswith(marker_prefix)),
                   key=lambda b: int(b[len(marker_prefix):]))
    if len(names) < 3:
        raise ValueError(f"need >= 3 table markers '{marker_prefix}<i>' in the OptiTrack stream, "
                         f"found {names}")
    measured = np.array([optitrack[b][["x", "y", "z"]].median().to_numpy() for b in names])
    known = TABLE_MARKERS[[int(b[len(marker_prefix):]) for b in names]]
    return fit_optitrack_to_table(measured, known)
