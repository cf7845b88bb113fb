"""A pinhole camera with OpenCV lens distortion, shared by the twin and perception.

Conventions are OpenCV's: x_cam = R @ x_world + t, pixels from cv2.projectPoints with the
5-coefficient distortion (k1, k2, p1, p2, k3). The world is the table frame.
"""

from dataclasses import dataclass

import cv2
import numpy as np

UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 1e-12)


@dataclass(frozen=True)
class Camera:
    name: str
    K: np.ndarray  # 3x3 intrinsics, pixels
    dist: np.ndarray  # (5,) k1 k2 p1 p2 k3
    R: np.ndarray  # 3x3 world -> camera rotation
    t: np.ndarray  # (3,) world -> camera translation, m
    width: int
    height: int

    @property
    def center(self) -> np.ndarray:
        """Camera centre in the world frame, m."""
        return -self.R.T @ self.t

    @property
    def P(self) -> np.ndarray:
        """3x4 projection matrix K [R | t] of the undistorted camera."""
        return self.K @ np.hstack([self.R, self.t[:, None]])

    def project(self, points: np.ndarray) -> np.ndarray:
        """Distorted pixel coordinates (N, 2) of world points (N, 3)."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if len(pts) == 0:
            return np.zeros((0, 2))
        rvec, _ = cv2.Rodrigues(self.R)
        px, _ = cv2.projectPoints(pts, rvec, self.t.astype(np.float64), self.K, self.dist)
        return px.reshape(-1, 2)

    def depth(self, points: np.ndarray) -> np.ndarray:
        """Depth along the optical axis (N,) of world points (N, 3), m."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        return pts @ self.R[2] + self.t[2]

    def undistort_pixels(self, pixels: np.ndarray) -> np.ndarray:
        """Undistorted pixel coordinates (N, 2) of distorted pixels (N, 2), same K."""
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 1, 2)
        if len(px) == 0:
            return np.zeros((0, 2))
        # OpenCV's default 5 iterations leave ~0.1 px at the corners of a strong barrel lens
        out = cv2.undistortPoints(px, self.K, self.dist, None, self.K, None, UNDISTORT_CRITERIA)
        return out.reshape(-1, 2)

    def to_dict(self) -> dict:
        return {
            "name": self.name, "K": self.K.tolist(), "dist": self.dist.tolist(),
            "R": self.R.tolist(), "t": self.t.tolist(), "width": self.width, "height": self.height,
        }

    @classmethod
    def from_dict(cls, d: dict) -> "Camera":
        return cls(
            name=d["name"], K=np.asarray(d["K"], float), dist=np.asarray(d["dist"], float),
            R=np.asarray(d["R"], float), t=np.asarray(d["t"], float),
            width=int(d["width"]), height=int(d["height"]),
        )


def look_at(eye: np.ndarray, target: np.ndarray, up=(0.0, 0.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """World->camera (R, t) of a camera at `eye` looking at `target` (OpenCV axes: z forward, y down)."""
    eye = np.asarray(eye, float)
    z = np.asarray(target, float) - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, np.asarray(up, float))
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.vstack([x, y, z])
    return R, -R @ eye
