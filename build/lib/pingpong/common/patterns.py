"""Calibration targets of the lab, shared by the twin (which draws them) and perception (which finds them).

- `CHECKERBOARD`: the hand-held intrinsics board (`raw/calibration/cam{c}/intrinsics_*.png`).
- `TABLE_CHARUCO`: a ChArUco mat lying flat on the table top for the extrinsics shot
  (`raw/calibration/cam{c}/table.png`). The net is taken off for that shot. Its corner ids map to
  table-frame points through `table_pattern_object_points`, ready for cv2.solvePnP.
- `TABLE_MARKERS`: OptiTrack markers stuck on the four table corners; perception finds the
  OptiTrack-to-table transform by Kabsch between their streamed and these table-frame positions.
"""

from dataclasses import dataclass

import cv2
import numpy as np

from pingpong.frames import TABLE_HALF_LENGTH, TABLE_HALF_WIDTH


@dataclass(frozen=True)
class Checkerboard:
    """A printed checkerboard; inner-corner grid as cv2.findChessboardCorners counts it."""

    inner_cols: int = 9
    inner_rows: int = 6
    square: float = 0.040  # m
    margin: float = 0.040  # white paper around the squares (the quiet zone the detector needs), m

    @property
    def pattern_size(self) -> tuple[int, int]:
        """(cols, rows) of inner corners, the `patternSize` argument of cv2.findChessboardCorners."""
        return (self.inner_cols, self.inner_rows)

    @property
    def size(self) -> tuple[float, float]:
        """Printed sheet (width, height) including the margin, m."""
        return ((self.inner_cols + 1) * self.square + 2 * self.margin,
                (self.inner_rows + 1) * self.square + 2 * self.margin)

    def object_points(self) -> np.ndarray:
        """Inner corners (cols*rows, 3) in the board frame (z = 0), row by row, m.

        The board frame's origin is the first inner corner; the outermost squares span
        [-square, inner_cols * square] in x and likewise in y.
        """
        xs, ys = np.meshgrid(np.arange(self.inner_cols), np.arange(self.inner_rows))
        return np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1) * self.square


@dataclass(frozen=True)
class TableCharuco:
    """A ChArUco mat centred on the table top: x of the board along table x, board y along table -y.

    Viewed from above with table +y pointing up, the print reads the right way round (as
    `board().generateImage` draws it). Board point (bx, by, 0) lies at table point
    (center_x - width/2 + bx, center_y + length/2 - by, surface_z).
    """

    # Large squares over the whole top: the cameras see it from 3-5 m at a grazing 20-30 deg, so at
    # 480x360 the far squares are ~10 px deep. Refine corners with a small cornerSubPix window
    # (2x2 at 480x360, scaled with resolution): larger windows reach into the markers.
    squares_x: int = 4  # along table x
    squares_y: int = 7  # along table y
    square: float = 0.38  # m
    marker: float = 0.25  # m
    dictionary: int = cv2.aruco.DICT_4X4_50
    center_x: float = 0.0  # m, table frame
    center_y: float = 0.0
    surface_z: float = 0.0  # printed mat, thickness negligible

    @property
    def size(self) -> tuple[float, float]:
        """(width along table x, length along table y), m."""
        return (self.squares_x * self.square, self.squares_y * self.square)

    def board(self) -> cv2.aruco.CharucoBoard:
        dictionary = cv2.aruco.getPredefinedDictionary(self.dictionary)
        return cv2.aruco.CharucoBoard((self.squares_x, self.squares_y), self.square, self.marker, dictionary)

    def board_to_table(self, board_points: np.ndarray) -> np.ndarray:
        """Table-frame points (N, 3) of board-frame points (N, 2 or 3), m."""
        bp = np.asarray(board_points, float).reshape(-1, np.shape(board_points)[-1])
        width, length = self.size
        return np.stack([self.center_x - width / 2 + bp[:, 0], self.center_y + length / 2 - bp[:, 1],
                         np.full(len(bp), self.surface_z)], axis=1)


CHECKERBOARD = Checkerboard()
TABLE_CHARUCO = TableCharuco()


def table_pattern_object_points(ids: np.ndarray, pattern: TableCharuco = TABLE_CHARUCO) -> np.ndarray:
    """Table-frame positions (N, 3) of ChArUco corner ids (N,) as cv2.aruco.CharucoDetector reports them."""
    corners = pattern.board().getChessboardCorners()
    return pattern.board_to_table(corners[np.asarray(ids, int).ravel()])


# OptiTrack markers on the table (14 mm spheres glued on the four corners of the top): their
# centres are one marker radius above the surface. Streamed as position-only rigid bodies
# `/optitrack/table_marker_{i}` (identity orientation), see pingpong.twin.optitrack_sim.
TABLE_MARKER_RADIUS = 0.007  # m
TABLE_MARKERS = np.array([
    [TABLE_HALF_WIDTH, TABLE_HALF_LENGTH, TABLE_MARKER_RADIUS],
    [-TABLE_HALF_WIDTH, TABLE_HALF_LENGTH, TABLE_MARKER_RADIUS],
    [-TABLE_HALF_WIDTH, -TABLE_HALF_LENGTH, TABLE_MARKER_RADIUS],
    [TABLE_HALF_WIDTH, -TABLE_HALF_LENGTH, TABLE_MARKER_RADIUS],
])
