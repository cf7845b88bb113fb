"""Rigid transforms: 4x4 homogeneous matrices, quaternions, and fitting one to point pairs.

A transform named `T_a_from_b` maps points in frame b to frame a: p_a = R @ p_b + t.
Quaternions are scalar-last (x, y, z, w), as OptiTrack and SciPy write them.
"""

import numpy as np
from scipy.spatial.transform import Rotation


def make_transform(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """4x4 homogeneous transform from a 3x3 rotation and a (3,) translation."""
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


def invert_transform(T: np.ndarray) -> np.ndarray:
    """Inverse of a rigid 4x4 transform (uses R^T rather than a general matrix inverse)."""
    R, t = T[:3, :3], T[:3, 3]
    return make_transform(R.T, -R.T @ t)


def apply_transform(T: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Points (..., 3) mapped by the 4x4 transform T; NaN points stay NaN."""
    return np.asarray(points, float) @ T[:3, :3].T + T[:3, 3]


def rotate_matrices(T: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """Orientations (..., 3, 3) expressed in T's target frame: R_a = R_ab @ R_b."""
    return T[:3, :3] @ np.asarray(rotations, float)


def quat_xyzw_to_matrix(quats_xyzw: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of quaternions (..., 4), scalar last; normalises them."""
    q = np.asarray(quats_xyzw, float)
    return Rotation.from_quat(q.reshape(-1, 4)).as_matrix().reshape(*q.shape[:-1], 3, 3)


def matrix_to_quat_xyzw(rotations: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4), scalar last with w >= 0, of rotation matrices (..., 3, 3)."""
    R = np.asarray(rotations, float)
    q = Rotation.from_matrix(R.reshape(-1, 3, 3)).as_quat(canonical=True)
    return q.reshape(*R.shape[:-2], 4)


def fit_rigid_transform(points_from: np.ndarray, points_to: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares rigid transform T (4x4) with points_to ~ T(points_from), and its RMS residual (m).

    Kabsch: the rotation aligning the centred point sets (SciPy's align_vectors solves exactly
    this SVD problem), then the translation between the centroids. Needs K >= 3 point pairs
    that are not collinear, otherwise the rotation about their line is undetermined.
    """
    src = np.asarray(points_from, float)
    dst = np.asarray(points_to, float)
    if src.shape != dst.shape or src.ndim != 2 or src.shape[1] != 3:
        raise ValueError(f"need two (K, 3) arrays of matching points, got {src.shape} and {dst.shape}")
    if not (np.isfinite(src).all() and np.isfinite(dst).all()):
        raise ValueError("point pairs contain NaN or inf")
    src_mean, dst_mean = src.mean(axis=0), dst.mean(axis=0)
    src_c, dst_c = src - src_mean, dst - dst_mean
    spread = np.linalg.svd(src_c, compute_uv=False) if len(src) >= 3 else np.zeros(1)
    if len(src) < 3 or spread[1] <= 1e-9 * max(spread[0], 1e-12):
        raise ValueError(f"need >= 3 non-collinear point pairs to fit a rotation, got {len(src)}")
    rotation, _ = Rotation.align_vectors(dst_c, src_c)
    R = rotation.as_matrix()
    T = make_transform(R, dst_mean - R @ src_mean)
    residual = apply_transform(T, src) - dst
    rms = float(np.sqrt(np.mean(np.sum(residual**2, axis=1))))
    return T, rms
