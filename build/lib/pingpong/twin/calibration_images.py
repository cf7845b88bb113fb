"""The calibration shots a lab takes before recording: checkerboard views and the table mat.

`raw/calibration/cam{c}/intrinsics_{i:02d}.png`: the hand-held checkerboard (patterns.CHECKERBOARD)
at varied distances, tilts and places covering the image, over the empty lab.
`raw/calibration/cam{c}/table.png`: the ChArUco mat (patterns.TABLE_CHARUCO) on the table, net off.
Both are rendered by exact inverse mapping with 4x4 subsamples per pixel (see render.py), so
OpenCV's corner refinement sees correctly anti-aliased edges.
"""

from pathlib import Path

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from pingpong.common.atomic import write_bytes_atomic
from pingpong.common.camera import Camera
from pingpong.common.patterns import CHECKERBOARD, TABLE_CHARUCO, Checkerboard, TableCharuco
from pingpong.twin.render import (
    Background,
    Lab,
    add_sensor_noise,
    average_subsamples,
    render_background,
    subpixel_rays,
)

PAPER, INK = 225.0, 28.0  # grey levels of the printed board facing the light


def _sheet_corners(board: Checkerboard) -> np.ndarray:
    lo = -board.square - board.margin
    hi_x = board.inner_cols * board.square + board.margin
    hi_y = board.inner_rows * board.square + board.margin
    return np.array([[lo, lo, 0], [hi_x, lo, 0], [hi_x, hi_y, 0], [lo, hi_y, 0]])


def checkerboard_poses(camera: Camera, n_views: int, rng: np.random.Generator,
                       board: Checkerboard = CHECKERBOARD) -> list[tuple[np.ndarray, np.ndarray]]:
    """Board-to-camera (R, t) of `n_views` hand-held views: spread over a 3x3 grid of image places,
    30-60 % of the image width, tilted up to 40 deg, the whole sheet inside the image."""
    f = camera.K[0, 0]
    sheet = _sheet_corners(board)
    centre_local = sheet.mean(axis=0)
    width = np.ptp(sheet[:, 0])
    poses = []
    while len(poses) < n_views:
        cell = len(poses) % 9
        for _ in range(200):
            target = np.array([(cell % 3 + 0.5) / 3 * camera.width, (cell // 3 + 0.5) / 3 * camera.height])
            target += rng.uniform(-0.12, 0.12, 2) * [camera.width, camera.height]
            depth = f * width / (rng.uniform(0.3, 0.6) * camera.width)
            ray = camera.undistort_pixels(target)[0]
            centre = np.array([(ray[0] - camera.K[0, 2]) / f, (ray[1] - camera.K[1, 2]) / camera.K[1, 1],
                               1.0])
            tilt = np.radians(rng.uniform(-40, 40, 2))
            R = Rotation.from_euler("xyz", [tilt[0], tilt[1], np.radians(rng.uniform(-15, 15))]).as_matrix()
            t = centre * depth - R @ centre_local
            px, _ = cv2.projectPoints(sheet, cv2.Rodrigues(R)[0], t, camera.K, camera.dist)
            px = px.reshape(-1, 2)
            if (px.min(axis=0) >= 2).all() and (px[:, 0] <= camera.width - 3).all() \
                    and (px[:, 1] <= camera.height - 3).all():
                poses.append((R, t))
                break
        else:
            raise RuntimeError(f"{camera.name}: no checkerboard pose fits image cell {cell}")
    return poses


def render_checkerboard_view(camera: Camera, background: Background, R: np.ndarray, t: np.ndarray,
                             rng: np.random.Generator, board: Checkerboard = CHECKERBOARD, ss: int = 4
                             ) -> np.ndarray:
    """The board at board-to-camera pose (R, t) over the empty lab, (H, W, 3) uint8 BGR."""
    px, _ = cv2.projectPoints(_sheet_corners(board), cv2.Rodrigues(R)[0], t, camera.K, camera.dist)
    px = px.reshape(-1, 2)
    # the distorted sheet may bulge past its corners' bounding box; pad by a few pixels
    x0, y0 = np.maximum(np.floor(px.min(axis=0)).astype(int) - 4, 0)
    x1 = min(int(np.ceil(px[:, 0].max())) + 5, camera.width)
    y1 = min(int(np.ceil(px[:, 1].max())) + 5, camera.height)
    rays = subpixel_rays(background.ray_map, x0, y0, x1 - x0, y1 - y0, ss)
    d = np.concatenate([rays, np.ones(rays.shape[:-1] + (1,))], axis=-1)
    normal = R[:, 2]
    s = (normal @ t) / (d @ normal)
    local = (s[..., None] * d - t) @ R  # board-frame points (R^T (p - t))
    bx, by = local[..., 0], local[..., 1]
    sheet = _sheet_corners(board)
    on_sheet = (bx >= sheet[0, 0]) & (bx <= sheet[2, 0]) & (by >= sheet[0, 1]) & (by <= sheet[2, 1]) & (s > 0)
    col, row = np.floor(bx / board.square), np.floor(by / board.square)
    in_squares = (col >= -1) & (col < board.inner_cols) & (row >= -1) & (row < board.inner_rows)
    black = in_squares & ((col + row) % 2 == 0)
    light = 0.8 + 0.2 * abs(normal[2])  # facing the camera (and the light behind it) is brightest
    grey = np.where(black, INK, PAPER) * light
    alpha = average_subsamples(on_sheet[..., None].astype(np.float32), ss)
    colour = average_subsamples((grey * on_sheet)[..., None].astype(np.float32), ss)
    image = background.image.copy()
    roi = image[y0:y1, x0:x1].astype(np.float32)
    image[y0:y1, x0:x1] = np.clip(roi * (1 - alpha) + colour + 0.5, 0, 255).astype(np.uint8)
    add_sensor_noise(image, background, rng)
    return image


def render_table_view(camera: Camera, lab: Lab, rng: np.random.Generator,
                      pattern: TableCharuco = TABLE_CHARUCO,
                      ray_map: np.ndarray | None = None) -> np.ndarray:
    """The ChArUco mat lying on the table (net taken off), (H, W, 3) uint8 BGR."""
    background = render_background(camera, lab, rng, net=False, table_pattern=pattern, ss=4, ray_map=ray_map)
    image = background.image.copy()
    add_sensor_noise(image, background, rng)
    return image


def write_calibration_images(folder: str | Path, cameras: list[Camera], lab: Lab, rng: np.random.Generator,
                             n_views: int = 20) -> None:
    """`folder`/cam{c}/intrinsics_{i:02d}.png (n_views each) and `folder`/cam{c}/table.png, atomically."""
    for index, camera in enumerate(cameras):
        out = Path(folder) / f"cam{index}"
        background = render_background(camera, lab, rng)
        for i, (R, t) in enumerate(checkerboard_poses(camera, n_views, rng)):
            image = render_checkerboard_view(camera, background, R, t, rng)
            write_bytes_atomic(out / f"intrinsics_{i:02d}.png", cv2.imencode(".png", image)[1].tobytes())
        table = render_table_view(camera, lab, rng, ray_map=background.ray_map)
        write_bytes_atomic(out / "table.png", cv2.imencode(".png", table)[1].tobytes())
