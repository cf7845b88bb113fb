"""Multi-view triangulation of ball centres and body joints, vectorised over all points (the pose's
assembly from people matched across views is perception.pose3d).

Points are triangulated by the linear DLT on undistorted pixels, as one batched 4x4 eigenproblem over
all points (OpenCV's cv2.triangulatePoints solves the same system but only for two views and,
called per point, is orders of magnitude slower; see benchmarks/bench_triangulation.py).
Outlier views are rejected by their reprojection error through the real (distorted) lens.

The ball's 2D views after the cameras' agreement (issue 49: a 2D candidate kept only where it agrees with
the other views and the 3D flight). Inputs: per camera its detections (DETECTIONS) and every candidate its
detector weighed (BALL_CANDIDATES), the calibration, the gate (reprojection_gate_px). agreed_views:
1. The detections triangulated (triangulate_robust: the largest set of views within the gate).
2. A frame with a point: a view it leaves out (a camera's detection on a held ball, a shirt, or none) takes
   that camera's candidate nearest the point's reprojection within the gate (rescue_views).
3. A frame without one: a camera's detection with the other cameras' candidates on its epipolar line
   (paired_views), in runs of perception.ball_pair_min_frames frames or more; in the frames still without
   one, the same from each camera's candidates refused 'slow' (a ball rolling on the table after a rally,
   refused by every camera: no detection to start from).
   The candidates of 2 and 3 are of any reason but NOT_A_VIEW's.
3b. A point of 3 or more views: a camera's view swapped for its candidate nearest the point of the others,
   where that is nearer by half the gate (swapped_views: a blob beside the ball within the gate).
4. The points triangulated again; their 3D ball is on the ball's flight or a phantom (ball_flight).
corrected_views then gives each camera's ball: a point on the ball's 3D track (on_ball_tracks: its flights
and the hops and rolls that continue them) takes the views it used, so a contradicted detection is
dropped and an agreeing candidate taken; a point on a track of no ball (a held ball, a cap) loses its
views; a frame where no views agree, or whose point's track is too short to judge, keeps every camera's
detection. The triangulation stage writes these as interim/ball_views/; the 3D ball's points in flight
are triangulated from exactly these views. Cost: 0.04 ms a frame of 3 cameras (one CPU, the tiny run with
twin.room below: 8,442 frames, 105k candidates; 0.025 ms without candidates).

Measured on the tiny run with twin.room (`snakemake -c2 reports/tables/perception_accuracy.md --configfile
config/test/tiny.yaml config/twin_room.yaml` at ed9973c, the room since 33196b3 config/config.yaml's
with one more ball at rest on the table; cameras 0-2, 8,442 frames): recall of the visible ball 97.04 /
99.04 / 98.47 % -> 99.88 / 99.93 / 99.68 %, false detections 0.20 / 0.09 / 0.28 % -> 0.14 / 0.09 / 0.09 %
(of frames, within 5 px: reports.perception_accuracy); 3D ball median error 1.379 -> 1.384 mm (p99 7.8 mm,
max 32 mm both), 6,865 -> 6,957 points in flight (before: 6fb8228's rescue_views alone). Most of the
single-view misses (169 of cam0's 199, 51 of cam2's 96) were the ball dribbling over the net at 0.2-0.8 m/s
after a rally, kept by cam1's track and refused 'slow' / 'non_ballistic' by the others: step 3 with the
hops' track (on_ball_tracks). Without step 3's runs (every pairing taken) cam0 / cam1 false were 0.05 / 0.13
% and 5 of the 3D points in flight lay 2.8-171 cm off the truth (cam2's lone detection with a blob on its
line where the ball was hidden from the others); without step 3 and with every phantom's views dropped (no
track rule) recall was 96.75 / 99.33 / 98.04 % (the dribble's 3D points are no flight); with the views of
tracks too short to judge dropped too, the plain tiny run (config/test/tiny.yaml, the colour method, whose
candidates are its detections) lost 1 / 1 / 2 right detections, now none (recall 99.84 / 100 / 99.79 %,
false 0 / 0 / 0.01 %, as its single-view rows). What is left: frames where no camera keeps the ball and no
other agrees (cut by the border: 'edge'), and lone detections of other objects that no other camera's
candidate agrees with (cam0's 12 false frames).

Held out (the same run with config `seed: 20261207`, 5,856 frames; nothing tuned on it): recall 99.47 /
99.75 / 99.31 % -> 99.63 / 99.78 / 99.52 %, false 0 / 0.43 / 0.09 % -> 0.03 / 0.36 / 0.09 %; cam0's 2 new
false frames are candidates within 2.3 px of the ball's true centre where the truth has it hidden
(visibility 0); 3D ball 4,581 points, median 1.57 mm, as without candidates. Dropping lone detections far in
time from any 3D ball (counted, not built: on the first run cam0's 7 lone views 30-100 frames from one were
all false) would have cost cam0 12 right views here.
"""

import logging
from itertools import combinations

import numpy as np
import pandas as pd

from pingpong.common.camera import Camera
from pingpong.frames import BALL_RADIUS, TABLE_HALF_LENGTH, TABLE_HALF_WIDTH
from pingpong.perception.ball_flight import FlightRule, link_tracks, phantom_reasons

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


# BALL_CANDIDATES reasons of candidates that may never be a view: 'static', a track at rest (a floor ball, a
# ball on the table: no ball in play, even where a flight's reprojection passes near it), and 'size' and
# 'edge', blobs above the area range or cut by the border, centred on their box rather than on a ball. Every
# other reason may be (kept, off_track, rank, lone, short, slow, non_ballistic, colour): a slow apex or a
# flight along one camera's axis is refused 'slow' or 'non_ballistic' by that camera alone while the others
# see it fly.
NOT_A_VIEW = ("static", "size", "edge")


def _candidates_on_frames(table: pd.DataFrame, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(frame rows among `times`, uv (K, 2)) of a camera's candidates (BALL_CANDIDATES) at those frame times,
    those of a NOT_A_VIEW reason left out."""
    table = table[~table["reason"].isin(NOT_A_VIEW)]
    row = np.minimum(np.searchsorted(times, table["time_ns"].to_numpy()), len(times) - 1)
    on = times[row] == table["time_ns"].to_numpy()
    return row[on], table[["u", "v"]].to_numpy(float)[on]


def _least_per_frame(rows: np.ndarray, *keys: np.ndarray) -> np.ndarray:
    """Indices into rows (K,) of each frame's entry of the least keys (each (K,), the last the first
    compared), the first such entry on ties."""
    order = np.lexsort((*keys, rows))  # stable
    return order[np.r_[True, rows[order][1:] != rows[order][:-1]]] if len(order) else order


def _nearest_candidates(table: pd.DataFrame, times: np.ndarray, wanted: np.ndarray, targets: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(frame rows, uv (K, 2), distance px (K,)) of a camera's candidate nearest targets[row] (N, 2) in each
    frame where wanted (N,) holds; candidates of a NOT_A_VIEW reason are never taken."""
    rows, uv = _candidates_on_frames(table, times)
    rows, uv = rows[wanted[rows]], uv[wanted[rows]]
    distance = np.hypot(*(uv - targets[rows]).T)
    first = _least_per_frame(rows, distance)
    return rows[first], uv[first], distance[first]


def rescue_views(cameras: list[Camera], times: np.ndarray, px: np.ndarray, tri: dict,
                 candidates: list[pd.DataFrame], max_reproj_px) -> np.ndarray:
    """px (N, C, 2) with each view that the triangulation `tri` of px left out (a camera's detection refused
    by the other views, or none) replaced by that camera's candidate nearest the point's reprojection, where
    it lies within the camera's gate; the rest unchanged. candidates: per camera, every ball candidate its
    detector weighed (BALL_CANDIDATES' time_ns, u, v, reason), at frame times among `times`; those of a
    NOT_A_VIEW reason are never taken.

    A camera's track can follow the wrong blob (a held ball, a shirt) while the others see the ball: the 2D
    candidate consistent with their 3D point is the ball, whatever the camera's own track chose."""
    out = px.copy()
    gate = np.broadcast_to(np.asarray(max_reproj_px, float), (len(cameras),))
    has_point = np.isfinite(tri["points"]).all(axis=1)
    for c, (camera, table) in enumerate(zip(cameras, candidates, strict=True)):
        open_view = has_point & ~tri["used_mask"][:, c]
        if not open_view.any():
            continue
        targets = np.full((len(times), 2), np.nan)
        targets[open_view] = camera.project(tri["points"][open_view])
        rows, uv, distance = _nearest_candidates(table, times, open_view, targets)
        near = distance <= gate[c]
        out[rows[near], c] = uv[near]
    return out


def swapped_views(cameras: list[Camera], times: np.ndarray, px: np.ndarray, tri: dict,
                  candidates: list[pd.DataFrame], max_reproj_px) -> np.ndarray:
    """px (N, C, 2) with a used view of a point seen by 3 or more cameras replaced by that camera's candidate
    nearest the point of its OTHER used views, where the candidate lies within the gate of it and nearer
    than the view by half the gate; the rest unchanged (candidates, gate: rescue_views').

    A camera's track can take a blob beside the ball (the server's held ball 5 px from a slow serve toss at
    480x360) within the gate of the point it pulls towards itself: rescue_views never sees it, since the view
    is used. Triangulated without it, the others' point shows which blob is the ball. On the tiny run of
    fb4dc53 (the club room) such a view made the 3D ball's largest error, 32 mm."""
    out = px.copy()
    gate = np.broadcast_to(np.asarray(max_reproj_px, float), (len(cameras),))
    used = tri["used_mask"] & (tri["n_views"] >= 3)[:, None]
    undistorted = np.full_like(px, np.nan)
    for c, camera in enumerate(cameras):
        seen = used[:, c]
        undistorted[seen, c] = camera.undistort_pixels(px[seen, c])
    P = np.stack([camera.P for camera in cameras])
    for c, (camera, table) in enumerate(zip(cameras, candidates, strict=True)):
        if not used[:, c].any():
            continue
        others = used.copy()
        others[:, c] = False
        targets = np.full((len(times), 2), np.nan)
        targets[used[:, c]] = camera.project(triangulate_dlt(P, undistorted[used[:, c]], others[used[:, c]]))
        rows, uv, distance = _nearest_candidates(table, times, used[:, c], targets)
        own = np.hypot(*(px[rows, c] - targets[rows]).T)
        better = (distance <= gate[c]) & (distance + gate[c] / 2 < own)
        out[rows[better], c] = uv[better]
    return out


def paired_views(cameras: list[Camera], times: np.ndarray, px: np.ndarray, open_frame: np.ndarray,
                 seeds: list[tuple[np.ndarray, np.ndarray]], candidates: list[pd.DataFrame], max_reproj_px,
                 min_views: int = 2, min_run_frames: int = 1, where=None) -> tuple[np.ndarray, np.ndarray]:
    """(px (N, C, 2) with the open frames (N,) replaced by the views of the best hypothesis of a seed and
    other cameras' candidates that agree with it, where one has at least min_views views (and its point
    satisfies `where`, a function of points (S, 3) to (S,) bools, where given), the rest unchanged; which
    frames (N,) were replaced).
    seeds: per camera, (frame rows (S,), uv (S, 2)) of the 2D balls to start from, any number a frame (its
    detections, or candidates: agreed_views); candidates: as rescue_views'.

    A hypothesis starts from a seed and takes, in each other camera, the candidate whose two-view point with
    the seed reprojects within both cameras' gates (the lowest RMS of those): the candidate on the seed's
    epipolar line. Its views are then triangulated together (triangulate_robust); the frame takes the
    hypothesis of the most views, then the lowest RMS, then the first camera's. A ball that one camera's track
    keeps while the others refuse it (a ball dribbling over the net at 0.5 m/s is 'slow' in a camera that
    sees it move along its axis) has no second detection to agree with: its candidates do. Only runs of
    at least min_run_frames consecutive frames so paired are taken: a seed's epipolar line crosses some
    other blob now and then where the ball is hidden from the other cameras, for a frame or a few (the
    tiny run with twin.room: of 29 runs of 1-5 frames, 63 of their 100 views were not the ball; of 2 runs
    of 15 frames or more, 2 of 338). Loops over camera pairs, never over frames."""
    n_cams = px.shape[1]
    gate = np.broadcast_to(np.asarray(max_reproj_px, float), (n_cams,))
    aligned = [_candidates_on_frames(table, times) for table in candidates]  # once, not per camera pair
    frames, hypotheses = [], []
    for seed, (rows, uv) in enumerate(seeds):
        rows, uv = rows[open_frame[rows]], uv[open_frame[rows]]
        hypothesis = np.full((len(rows), n_cams, 2), np.nan)
        hypothesis[:, seed] = uv
        for other in range(n_cams):
            if other != seed and len(rows):
                hypothesis[:, other] = _epipolar_candidates(
                    [cameras[seed], cameras[other]], rows, uv, *aligned[other], gate[[seed, other]])
        frames.append(rows)
        hypotheses.append(hypothesis)
    frames, hypotheses = np.concatenate(frames), np.concatenate(hypotheses)
    fit = triangulate_robust(cameras, hypotheses, gate, min_views)
    enough = fit["n_views"] >= min_views
    if where is not None:
        enough &= where(fit["points"])
    enough = np.flatnonzero(enough)
    best = enough[_least_per_frame(frames[enough], fit["reproj_rms_px"][enough], -fit["n_views"][enough])]
    taken = np.sort(frames[best])
    runs = np.split(taken, np.flatnonzero(np.diff(taken) > 1) + 1)
    long_run = np.isin(frames[best], np.concatenate([run for run in runs if len(run) >= min_run_frames]
                                                    + [np.zeros(0, int)]))
    best = best[long_run]
    out, taken = px.copy(), np.zeros(len(px), bool)
    out[frames[best]] = np.where(fit["used_mask"][best][..., None], hypotheses[best], np.nan)
    taken[frames[best]] = True
    return out, taken


def _epipolar_candidates(pair: list[Camera], seed_rows: np.ndarray, seed_px: np.ndarray, rows: np.ndarray,
                         uv: np.ndarray, gate: np.ndarray) -> np.ndarray:
    """Per seed pixel (S, 2) of pair[0] at its frame row (S,), the candidate of pair[1] (uv (K, 2) at frame
    rows (K,)) of the same frame whose two-view point with it reprojects within both gates (2,) px at the
    lowest RMS; NaN where none."""
    out = np.full((len(seed_rows), 2), np.nan)
    seed, other = _same_frame_pairs(seed_rows, rows)
    if len(seed) == 0:
        return out
    pixels = np.stack([seed_px[seed], uv[other]], axis=1)
    undistorted = np.stack([cam.undistort_pixels(pixels[:, k]) for k, cam in enumerate(pair)], axis=1)
    points = triangulate_dlt(np.stack([cam.P for cam in pair]), undistorted, np.ones((len(seed), 2), bool))
    errors = reprojection_errors(pair, points, pixels)
    agree = np.flatnonzero((errors <= gate).all(axis=1))
    rms = np.sqrt(np.mean(errors[agree] ** 2, axis=1))
    first = agree[_least_per_frame(seed[agree], rms)]  # per seed, the lowest RMS
    out[seed[first]] = pixels[first, 1]
    return out


def _same_frame_pairs(seed_rows: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(seed indices, candidate indices) of every seed (frame rows (S,)) with every candidate (frame rows
    (K,)) of its frame."""
    order = np.argsort(rows, kind="stable")
    start = np.searchsorted(rows[order], seed_rows, "left")
    count = np.searchsorted(rows[order], seed_rows, "right") - start
    seed = np.repeat(np.arange(len(seed_rows)), count)
    within = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    return seed, order[np.repeat(start, count) + within]


def agreed_views(cameras: list[Camera], detections: list[pd.DataFrame], max_reproj_px, min_views: int = 2,
                 candidates: list[pd.DataFrame] | None = None, min_run_frames: int = 1
                 ) -> dict[str, np.ndarray]:
    """The ball's views that agree, per camera frame: triangulate_robust's dict of the views (points,
    n_views, reproj_rms_px, used_mask) with `times` (N,), the detections' pixels `detected` (N, C, 2) (NaN
    where a camera has none) and the pixels triangulated, `pixels` (N, C, 2): the detections, and with
    candidates (per camera, BALL_CANDIDATES) the candidates that fill the views the detections leave out
    where they agree with the others (rescue_views) and, in runs of at least min_run_frames frames where no
    detections agree, the candidates that agree with one camera's detection (paired_views), then in the
    frames still open those that agree with a candidate refused 'slow' and make a point over the table top
    (over_table_top: a ball rolling out after a rally), the points then triangulated again."""
    times = _aligned_times(detections)
    px = np.stack([np.where(d["detected"].to_numpy()[:, None], d[["u", "v"]].to_numpy(), np.nan)
                   for d in detections], axis=1)
    tri, pixels = triangulate_robust(cameras, px, max_reproj_px, min_views), px
    if candidates is not None:
        pixels = rescue_views(cameras, times, px, tri, candidates, max_reproj_px)
        filled = _changed(px, pixels)
        open_frame = ~np.isfinite(tri["points"]).all(axis=1)
        pixels, paired_frame = paired_views(cameras, times, pixels, open_frame, view_seeds(px), candidates,
                                            max_reproj_px, min_views, min_run_frames)
        slow = [_candidates_on_frames(table[table["reason"] == "slow"], times) for table in candidates]
        pixels, slow_frame = paired_views(cameras, times, pixels, open_frame & ~paired_frame, slow,
                                          candidates, max_reproj_px, min_views, min_run_frames,
                                          where=over_table_top)
        paired = _changed(px, pixels) & ~filled
        if paired.any() or filled.any():
            tri = triangulate_robust(cameras, pixels, max_reproj_px, min_views)
        before = pixels
        pixels = swapped_views(cameras, times, pixels, tri, candidates, max_reproj_px)
        swapped = _changed(before, pixels)
        log.info("views filled by a camera's other ball candidates: %d where the others agree (per camera "
                 "%s), %d agreeing with a lone detection or a 'slow' candidate (per camera %s; frames: %d of "
                 "a detection, %d of a slow candidate); %d used views swapped for a candidate nearer the "
                 "others' point (per camera %s)", filled.sum(), filled.sum(axis=0).tolist(), paired.sum(),
                 paired.sum(axis=0).tolist(), paired_frame.sum(), slow_frame.sum(), swapped.sum(),
                 swapped.sum(axis=0).tolist())
        if swapped.any():
            tri = triangulate_robust(cameras, pixels, max_reproj_px, min_views)
    return tri | {"times": times, "detected": px, "pixels": pixels}


# The highest centre (m, table frame) of a ball rolling or hopping out over the table top after a rally:
# the ball's radius plus 6 cm of hop. The default run of 1754bef: of 1,544 points seeded from 'slow'
# candidates anywhere, 163 lay over the table top with z in [0, 0.08] m, all within 3 cm of the ball
# (s02's 1 s roll by the net: 103 frames); none of the other 1,381 (floor balls, held balls) was the ball.
ROLL_MAX_Z = BALL_RADIUS + 0.06


def over_table_top(points: np.ndarray) -> np.ndarray:
    """Which points (S, 3) m lie over the table top, centres at most ROLL_MAX_Z above it (NaN: False)."""
    with np.errstate(invalid="ignore"):
        return ((np.abs(points[:, 0]) <= TABLE_HALF_WIDTH) & (np.abs(points[:, 1]) <= TABLE_HALF_LENGTH)
                & (points[:, 2] >= 0) & (points[:, 2] <= ROLL_MAX_Z))


def view_seeds(px: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per camera, (frame rows, uv) of its views in px (N, C, 2), NaN none: paired_views' seeds."""
    seen = np.isfinite(px).all(axis=2)
    return [(np.flatnonzero(seen[:, c]), px[seen[:, c], c]) for c in range(px.shape[1])]


def _changed(before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """Which views (N, C) `after` holds that `before` does not (pixels (N, C, 2))."""
    return np.isfinite(after).all(axis=2) & ~(before == after).all(axis=2)


def ball3d_table(cameras: list[Camera], detections: list[pd.DataFrame], max_reproj_px,
                 min_views: int = 2, candidates: list[pd.DataFrame] | None = None, min_run_frames: int = 1
                 ) -> pd.DataFrame:
    """The ball's 3D centre per camera frame (BALL3D, table frame) of agreed_views."""
    return ball3d_frame(agreed_views(cameras, detections, max_reproj_px, min_views, candidates,
                                     min_run_frames))


def ball3d_frame(views: dict[str, np.ndarray]) -> pd.DataFrame:
    """A BALL3D table of agreed_views' dict."""
    return pd.DataFrame({"time_ns": views["times"], **dict(zip("xyz", views["points"].T, strict=True)),
                         "n_views": views["n_views"], "reproj_rms_px": views["reproj_rms_px"]})


def on_ball_tracks(times_ns: np.ndarray, points: np.ndarray, rule: FlightRule
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(which points (N,) of a session's 3D ball are the ball in play, which are no ball); times_ns (N,)
    increasing, points (N, 3) m, NaN unseen. The ball: the points of a 3D track (ball_flight.link_tracks)
    with a point in flight (phantom_reasons ''). A ball hopping and rolling out over the table after its
    last flight, at 0.2-0.8 m/s, is no flight (ball_flight's docstring) but continues the flight's track;
    a ball held in a hand, a floor ball rolling or a cap has a track of its own with no flight: no ball.
    A point too short to judge is neither: 'isolated' (the ball seen by two cameras for a frame or two
    between occlusions, on the plain tiny run) or 'short_flight' (ballistic, but for fewer frames than a
    flight: in the default run of 539b607, 69 views of the ball in s02's cameras, flying away into the room
    after a shot, 2-11 mm from its truth, whose views were dropped as no ball; judged neither, the 16
    cameras' multi-view recall rose by 0-0.30 points, their false detections unchanged)."""
    t_s = (np.asarray(times_ns, np.int64) - times_ns[:1]) * 1e-9
    reasons = phantom_reasons(t_s, points, rule)
    frame_s = float(np.median(np.diff(t_s))) if len(t_s) > 1 else 1.0  # as phantom_reasons takes it
    track = link_tracks(t_s, np.asarray(points, float), rule, frame_s)
    flights = np.unique(track[(track >= 0) & (reasons == "")])
    is_ball = (track >= 0) & np.isin(track, flights)
    return is_ball, (track >= 0) & ~is_ball & ~np.isin(reasons, ("isolated", "short_flight"))


def corrected_views(detected: np.ndarray, pixels: np.ndarray, used: np.ndarray, is_ball: np.ndarray,
                    no_ball: np.ndarray) -> np.ndarray:
    """Each camera's 2D ball after multi-view agreement (N, C, 2), NaN where none.

    detected (N, C, 2): each camera's own detection (NaN none); pixels (N, C, 2) and used (N, C): the views
    a frame's 3D point was triangulated from (agreed_views' pixels and used_mask: the detections and the
    candidates that filled views); is_ball, no_ball (N,): whether that point is the ball in play, or no
    ball (on_ball_tracks). Where the point is the ball a camera's ball is the view the point used: its
    detection where that agrees with the others, else the candidate that does, else none (its detection
    contradicts where the other views agree). Where the point is no ball (a held ball, a cap), the views
    it used are no ball, and a camera keeps its detection where the point did not use it (it may be the
    ball seen by that camera alone, where the point took another of its candidates); elsewhere (no views
    agree, or a point too short to judge) every camera keeps its own detection (nothing to check it
    against)."""
    was_used = used & (pixels == detected).all(axis=2)  # a camera's own detection among the point's views
    own = ~(is_ball | no_ball)[:, None] | (no_ball[:, None] & ~was_used)
    ball_view = is_ball[:, None] & used
    return np.where(ball_view[..., None], pixels, np.where(own[..., None], detected, np.nan))


def views_table(detections: pd.DataFrame, candidates: pd.DataFrame | None, uv: np.ndarray) -> pd.DataFrame:
    """A camera's DETECTIONS table of its corrected views uv (N, 2) px (NaN none) at its detections' frames:
    each view's area that of the detection or candidate it is (candidates: BALL_CANDIDATES, or None), the
    frames' decode_ok the detections'."""
    observed = [detections.loc[detections["detected"], ["time_ns", "u", "v", "area_px"]]]
    if candidates is not None:
        observed.append(candidates[["time_ns", "u", "v", "area_px"]])
    areas = pd.concat(observed).drop_duplicates(["time_ns", "u", "v"])
    views = pd.DataFrame({"time_ns": detections["time_ns"].to_numpy(), "u": uv[:, 0], "v": uv[:, 1]})
    views = views.merge(areas, on=["time_ns", "u", "v"], how="left")  # NaN u, v match nothing
    detected = np.isfinite(uv).all(axis=1)
    if views.loc[detected, "area_px"].isna().any():
        raise ValueError("a corrected view is neither a detection nor a candidate of its camera")
    return views.assign(area_px=views["area_px"].fillna(0).astype(detections["area_px"].dtype),
                        detected=detected, decode_ok=detections["decode_ok"].to_numpy())
