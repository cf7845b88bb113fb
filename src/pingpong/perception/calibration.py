"""Camera calibration: intrinsics from checkerboard views, extrinsics from the ChArUco mat on the table.

OpenCV does the work (findChessboardCorners + cornerSubPix, calibrateCamera, CharucoDetector,
solvePnP); this module only chains it and reports errors per camera. The calibration rule also fits
the OptiTrack-to-table transform from the table-corner markers (optitrack_to_table).
"""

import logging
from pathlib import Path

import cv2
import numpy as np
import pandas as pd

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
from pingpong.common.rigid import fit_rigid_transform
from pingpong.perception.schemas import CAMERAS

log = logging.getLogger(__name__)
SUBPIX = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-4)
OUTLIER_VIEW_FACTOR = 3.0  # a view whose RMS exceeds this many times the median view's is dropped


class CalibrationError(RuntimeError):
    pass


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


def calibrate_intrinsics(paths: list, board: Checkerboard = CHECKERBOARD) -> dict:
    """K, dist (k1 k2 p1 p2 k3), RMS reprojection error (px) and views used, from checkerboard images."""
    object_points, image_points, size, used = [], [], None, []
    for path in paths:
        gray = read_gray(path)
        size = gray.shape[::-1]
        corners = find_checkerboard(gray, board)
        if corners is None:
            log.warning("%s: checkerboard not found, view skipped", path)
            continue
        object_points.append(board.object_points().astype(np.float32))
        image_points.append(corners.astype(np.float32))
        used.append(str(path))
    if len(used) < 4:
        raise CalibrationError(f"only {len(used)} of {len(paths)} checkerboard views usable "
                               f"(need 4), e.g. {paths[:1]}")
    rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(object_points, image_points, size, None, None)
    # A board seen nearly edge-on gives poorly located corners that pull the whole fit:
    # drop views far worse than the typical one and fit again (once).
    view_rms = np.array([_view_rms(o, i, r, t, K, dist)
                         for o, i, r, t in zip(object_points, image_points, rvecs, tvecs, strict=True)])
    keep = view_rms <= OUTLIER_VIEW_FACTOR * np.median(view_rms)
    if not keep.all() and keep.sum() >= 4:
        for path in np.array(used)[~keep]:
            log.warning("%s: view reprojects %.2f px RMS (median %.2f), dropped", path,
                        view_rms[used.index(path)], np.median(view_rms))
        object_points = [o for o, k in zip(object_points, keep, strict=True) if k]
        image_points = [i for i, k in zip(image_points, keep, strict=True) if k]
        used = [u for u, k in zip(used, keep, strict=True) if k]
        rms, K, dist, _, _ = cv2.calibrateCamera(object_points, image_points, size, None, None)
    return {"K": K, "dist": dist.ravel()[:5], "rms_px": float(rms), "views": used, "size": size}


def _view_rms(obj, img, rvec, tvec, K, dist) -> float:
    projected, _ = cv2.projectPoints(obj, rvec, tvec, K, dist)
    return float(np.sqrt(np.mean(np.sum((projected.reshape(-1, 2) - img.reshape(-1, 2)) ** 2, axis=1))))


def extrinsics_from_table(path, K: np.ndarray, dist: np.ndarray,
                          pattern: TableCharuco = TABLE_CHARUCO) -> dict:
    """World(table)->camera R, t from the ChArUco mat on the table, with its reprojection RMS (px)."""
    gray = read_gray(path)
    detector = cv2.aruco.CharucoDetector(pattern.board())
    corners, ids, _, _ = detector.detectBoard(gray)
    if ids is None or len(ids) < 6:
        raise CalibrationError(f"{path}: the table's ChArUco mat is not visible enough "
                               f"({0 if ids is None else len(ids)} corners, need 6)")
    # Far squares are ~10 px deep at 480x360: a larger window would reach into the markers.
    half = max(2, round(2 * gray.shape[1] / 480))
    corners = cv2.cornerSubPix(gray, corners.astype(np.float32), (half, half), (-1, -1), SUBPIX)
    obj = table_pattern_object_points(ids.ravel(), pattern)
    ok, rvec, tvec = cv2.solvePnP(obj, corners, K, dist, flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        raise CalibrationError(f"{path}: solvePnP failed on {len(ids)} ChArUco corners")
    projected, _ = cv2.projectPoints(obj, rvec, tvec, K, dist)
    rms = float(np.sqrt(np.mean(np.sum((projected.reshape(-1, 2) - corners.reshape(-1, 2)) ** 2, axis=1))))
    return {"R": cv2.Rodrigues(rvec)[0], "t": tvec.ravel(), "rms_px": rms, "n_corners": int(len(ids))}


def calibrate_camera(name: str, intrinsics_paths: list, table_path) -> tuple[Camera, dict]:
    """One camera from its raw calibration captures, and its error report."""
    intr = calibrate_intrinsics(sorted(intrinsics_paths, key=str))
    extr = extrinsics_from_table(table_path, intr["K"], intr["dist"])
    camera = Camera(name, intr["K"], intr["dist"], extr["R"], extr["t"], *intr["size"])
    report = {"name": name, "intrinsics_rms_px": intr["rms_px"], "views_used": len(intr["views"]),
              "extrinsics_rms_px": extr["rms_px"], "table_corners": extr["n_corners"],
              "center": camera.center.tolist()}
    log.info("%s: intrinsics RMS %.3f px over %d views, extrinsics RMS %.3f px", name,
             intr["rms_px"], len(intr["views"]), extr["rms_px"])
    return camera, report


def camera_folder_paths(folder) -> tuple[list[Path], Path]:
    folder = Path(folder)
    return sorted(folder.glob("intrinsics_*.png")), folder / "table.png"




def load_cameras(path) -> tuple[list[Camera], dict]:
    """The calibrated cameras and the rest of interim/calibration/cameras.json."""
    payload = read_json(path, CAMERAS)
    return [Camera.from_dict(c) for c in payload["cameras"]], payload


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
