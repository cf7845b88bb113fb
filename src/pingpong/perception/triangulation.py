"""Multi-view triangulation of ball centres and body joints, vectorised over all points (the pose's
assembly from people matched across views is perception.pose3d).

Points are triangulated by the linear DLT on undistorted pixels, as one batched 4x4 eigenproblem over
all points (OpenCV's cv2.triangulatePoints solves the same system but only for two views and,
called per point, is orders of magnitude slower; see benchmarks/bench_triangulation.py).
Outlier views are rejected by their reprojection error through the real (distorted) lens.
"""

import logging
from itertools import combinations

import numpy as np
import pandas as pd

from pingpong.common.camera import Camera

log = logging.getLogger(__name__)


def triangulate_dlt(P: np.ndarray, pixels: np.ndarray, mask: np.ndarray, weights=None) -> np.ndarray:
    """World points (N, 3) from projection matrices P (C, 3, 4) and undistorted pixels (N, C, 2).

    mask (N, C) says which views to use; a point with fewer than two is NaN. Each used view
    contributes the rows u * P[2] - P[0] and v * P[2] - P[1] of the homogeneous system A X = 0
    (the rows of unused views are zeroed, which leaves the solution unchanged), scaled by its weight
    (N, C) when given (e.g. the keypoint's confidence, as Pose2Sim weights its DLT), and X is the
    right singular vector of A's smallest singular value, found as the eigenvector of A^T A (4x4) with
    the smallest eigenvalue: numpy runs LAPACK once per point, and eigh of the 4x4 took 18 s where the
    SVD of the (2C, 4) A took 44 s for the default run's s00 association (cProfile); the joints agree
    within 5e-14 m (A^T A squares A's condition number, but the gap to the null vector stays wide).
    """
    P = np.asarray(P, float)
    px = np.asarray(pixels, float)
    mask = np.asarray(mask, bool) & np.isfinite(px).all(axis=-1)
    px = np.where(mask[..., None], px, 0.0)
    rows = px[..., None] * P[None, :, 2:3, :] - P[None, :, 0:2, :]  # (N, C, 2, 4)
    if weights is not None:  # a view of weight 0 is no view
        weights = np.nan_to_num(np.asarray(weights, float))
        mask = mask & (weights > 0)
    n_points, n_cams = mask.shape
    scale = mask if weights is None else mask * weights
    A = (rows * scale[..., None, None]).reshape(n_points, 2 * n_cams, 4)
    _, vectors = np.linalg.eigh(np.einsum("nki,nkj->nij", A, A))
    X = vectors[:, :, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        points = X[:, :3] / X[:, 3:4]
    points[mask.sum(axis=1) < 2] = np.nan
    return points


def reprojection_errors(cameras: list[Camera], points: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    """Per-view distance (N, C) in pixels between the lens projection of points (N, 3) and the
    observed distorted pixels (N, C, 2); inf where the point lies behind the camera, NaN where unseen."""
    errors = np.full(pixels.shape[:2], np.nan)
    finite = np.isfinite(points).all(axis=1)
    for c, cam in enumerate(cameras):
        projected = cam.project(points[finite])
        err = np.linalg.norm(projected - pixels[finite, c], axis=1)
        err[cam.depth(points[finite]) <= 0] = np.inf  # projectPoints mirrors such points into view
        errors[finite, c] = err
    return errors


def reprojection_gate_px(cameras: list[Camera], share_of_diagonal: float) -> np.ndarray:
    """Each camera's outlier gate (C,) px: a share of its image diagonal, so that one setting holds from
    480x360 (0.005: 3.0 px, the gate the default run was tuned with) to 1920x1080 (11.0 px), where a
    fixed 3 px gate dropped 19 % of a real recording's joints and a 15 px gate left a 6 mm median."""
    return share_of_diagonal * np.array([np.hypot(c.width, c.height) for c in cameras], float)


def triangulate_robust(
    cameras: list[Camera], pixels_distorted: np.ndarray, max_reproj_px, min_views: int = 2, confidence=None,
    max_mean_px: float | None = None,
) -> dict[str, np.ndarray]:
    """Triangulate points (N, 3) seen in distorted pixels (N, C, 2), NaN where a camera missed them.

    Tries every camera subset with at least `min_views` views, largest first; a point takes the
    largest subset it is seen in whose views all reproject within `max_reproj_px` (px: one gate, or
    one per camera (C,), see reprojection_gate_px), the lowest RMS among subsets of that size, so
    one bad view is dropped rather than pulling the point off. With max_mean_px (px) a subset is
    accepted instead when its views' mean reprojection error is within it, the lowest mean among
    subsets of that size: Pose2Sim's rule, which drops the worst views until the mean is under its
    threshold. Points with no such subset are NaN with n_views 0. Loops over the (at most 2^C)
    subsets, never over points. For joints pass N = frames * joints. confidence (N, C), when given,
    weights each view's DLT rows (triangulate_dlt).

    Returns points (N, 3) in the cameras' world frame, n_views (N,), reproj_rms_px (N,) over
    the used views, and used_mask (N, C).
    """
    px = np.asarray(pixels_distorted, float)
    n_points, n_cams = px.shape[:2]
    if n_cams != len(cameras):
        raise ValueError(f"pixels have {n_cams} views but {len(cameras)} cameras were given")
    if min_views < 2:
        raise ValueError(f"min_views must be >= 2, got {min_views}")
    seen = np.isfinite(px).all(axis=-1)
    undistorted = np.full_like(px, np.nan)
    for c, cam in enumerate(cameras):
        undistorted[seen[:, c], c] = cam.undistort_pixels(px[seen[:, c], c])
    P = np.stack([cam.P for cam in cameras])
    gate = np.broadcast_to(np.asarray(max_reproj_px, float), (n_cams,))

    points = np.full((n_points, 3), np.nan)
    rms = np.full(n_points, np.nan)
    used = np.zeros((n_points, n_cams), bool)
    unresolved = seen.sum(axis=1) >= min_views
    for size in range(n_cams, min_views - 1, -1):
        best = np.full(n_points, np.inf)  # the score of the subset taken: RMS, or mean (max_mean_px)
        for subset in combinations(range(n_cams), size):
            views = list(subset)
            idx = np.flatnonzero(unresolved & seen[:, views].all(axis=1))
            if len(idx) == 0:
                continue
            weights = None if confidence is None else np.asarray(confidence, float)[idx][:, views]
            candidate = triangulate_dlt(P[views], undistorted[idx][:, views], np.ones((len(idx), size), bool),
                                        weights)
            err = reprojection_errors([cameras[c] for c in views], candidate, px[idx][:, views])
            candidate_rms = np.sqrt(np.mean(err**2, axis=1))
            if max_mean_px is None:
                accepted, score = (err <= gate[views]).all(axis=1), candidate_rms
            else:
                score = np.mean(err, axis=1)
                accepted = score <= max_mean_px
            better = accepted & (score < best[idx])
            take = idx[better]
            points[take] = candidate[better]
            rms[take] = candidate_rms[better]
            best[take] = score[better]
            used[take] = False
            used[np.ix_(take, views)] = True
        unresolved &= ~np.isfinite(best)
    return {"points": points, "n_views": used.sum(axis=1), "reproj_rms_px": rms, "used_mask": used}


def pose_gate_px(cameras: list[Camera], errors: np.ndarray, used: np.ndarray, share_of_diagonal: float,
                 noise_factor: float) -> np.ndarray:
    """Each camera's keypoint gate (C,) px: its share-of-diagonal gate (reprojection_gate_px), widened to
    noise_factor times the camera's median reprojection error (errors (N, C)) in an all-view fit of
    points with >= 3 used views (used (N, C); a 2-view fit splits its error between the views), so that
    real OpenPose noise (views 7-24 px apart at 1088x1920) keeps every view, where the twin's
    (about 1 px at 480x360) keeps the diagonal gate."""
    base = reprojection_gate_px(cameras, share_of_diagonal)
    many = used.sum(axis=1) >= 3
    noise = np.array([np.median(errors[many & used[:, c], c]) if (many & used[:, c]).any() else 0.0
                      for c in range(len(cameras))])
    return np.fmax(base, noise_factor * noise)


def _aligned_times(tables: list[pd.DataFrame]) -> np.ndarray:
    """The camera clock shared by every view (the cameras are synchronised: equal frame times)."""
    times = tables[0]["time_ns"].unique()
    for table in tables[1:]:
        if not np.array_equal(table["time_ns"].unique(), times):
            raise ValueError("camera frame times differ between views: the cameras must share a clock")
    return times


def rescue_views(cameras: list[Camera], times: np.ndarray, px: np.ndarray, tri: dict,
                 candidates: list[pd.DataFrame], max_reproj_px) -> np.ndarray:
    """px (N, C, 2) with each view that the triangulation `tri` of px left out (a camera's detection refused
    by the other views, or none) replaced by that camera's candidate nearest the point's reprojection, where
    it lies within the camera's gate; the rest unchanged. candidates: per camera, every ball candidate its
    detector weighed (BALL_CANDIDATES' time_ns, u, v), at frame times among `times`.

    A camera's track can follow the wrong blob (a held ball, a shirt) while the others see the ball: the 2D
    candidate consistent with their 3D point is the ball, whatever the camera's own track chose."""
    out = px.copy()
    gate = np.broadcast_to(np.asarray(max_reproj_px, float), (len(cameras),))
    has_point = np.isfinite(tri["points"]).all(axis=1)
    for c, (camera, table) in enumerate(zip(cameras, candidates, strict=True)):
        row = np.searchsorted(times, table["time_ns"].to_numpy())
        row = np.minimum(row, len(times) - 1)
        on_frame = times[row] == table["time_ns"].to_numpy()
        open_view = on_frame & has_point[row] & ~tri["used_mask"][row, c]
        if not open_view.any():
            continue
        rows = row[open_view]
        uv = table[["u", "v"]].to_numpy(float)[open_view]
        distance = np.hypot(*(uv - camera.project(tri["points"][rows])).T)
        order = np.lexsort((distance, rows))  # per frame, nearest first
        first = order[np.r_[True, rows[order][1:] != rows[order][:-1]]]
        near = first[distance[first] <= gate[c]]
        out[rows[near], c] = uv[near]
    return out


def ball3d_table(cameras: list[Camera], detections: list[pd.DataFrame], max_reproj_px,
                 min_views: int = 2, candidates: list[pd.DataFrame] | None = None) -> pd.DataFrame:
    """The ball's 3D centre per camera frame from each camera's detections (table frame). With candidates
    (per camera, BALL_CANDIDATES), views the detections leave out are filled by candidates that agree with
    the others (rescue_views) and the points triangulated again."""
    times = _aligned_times(detections)
    px = np.stack([np.where(d["detected"].to_numpy()[:, None], d[["u", "v"]].to_numpy(), np.nan)
                   for d in detections], axis=1)
    tri = triangulate_robust(cameras, px, max_reproj_px, min_views)
    if candidates is not None:
        rescued = rescue_views(cameras, times, px, tri, candidates, max_reproj_px)
        changed = (rescued != px).any(axis=2) & np.isfinite(rescued).all(axis=2)
        log.info("views filled by a camera's other ball candidates: %d (per camera %s)", changed.sum(),
                 changed.sum(axis=0).tolist())
        if changed.any():
            tri = triangulate_robust(cameras, rescued, max_reproj_px, min_views)
    return pd.DataFrame({"time_ns": times, **dict(zip("xyz", tri["points"].T, strict=True)),
                         "n_views": tri["n_views"], "reproj_rms_px": tri["reproj_rms_px"]})
