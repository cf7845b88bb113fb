"""Speed of the batched DLT against per-point baselines, measured side by side in one run.

Baselines: cv2.triangulatePoints called once per point and once for all points (two views; it
takes only two), a per-point numpy SVD loop (four views), and triangulate_robust called point by
point. Results are checked to agree before timing is reported.

    PYTHONPATH=src python benchmarks/bench_triangulation.py [--points 20000] [--repeats 3]
"""

import argparse

import cv2
import numpy as np
from timing import best_time

from pingpong.common.camera import Camera, look_at
from pingpong.perception.triangulation import triangulate_dlt, triangulate_robust


def lab_cameras(n: int) -> list[Camera]:
    K = np.array([[1400.0, 0, 960], [0, 1400.0, 540], [0, 0, 1]])
    cameras = []
    for c in range(n):
        azimuth = np.pi / 4 + 2 * np.pi * c / n
        R, t = look_at(np.array([4 * np.cos(azimuth), 4 * np.sin(azimuth), 2.5]), np.array([0, 0, 0.3]))
        cameras.append(Camera(f"cam{c}", K, np.array([-0.1, 0.05, 0, 0, 0]), R, t, 1920, 1080))
    return cameras


def cv2_per_point(P, pixels):
    out = np.empty((len(pixels), 3))
    for i in range(len(pixels)):
        X = cv2.triangulatePoints(P[0], P[1], pixels[i, 0].reshape(2, 1), pixels[i, 1].reshape(2, 1))
        out[i] = X[:3, 0] / X[3, 0]
    return out


def cv2_all_points_at_once(P, pixels):
    X = cv2.triangulatePoints(P[0], P[1], pixels[:, 0].T.copy(), pixels[:, 1].T.copy())
    return (X[:3] / X[3]).T


def svd_per_point(P, pixels):
    out = np.empty((len(pixels), 3))
    for i in range(len(pixels)):
        A = (pixels[i, :, :, None] * P[:, 2:3, :] - P[:, 0:2, :]).reshape(-1, 4)
        X = np.linalg.svd(A)[2][-1]
        out[i] = X[:3] / X[3]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=20_000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    cameras = lab_cameras(4)
    points = rng.uniform([-1.0, -2.0, 0.0], [1.0, 2.0, 1.8], size=(args.points, 3))
    P = np.stack([cam.P for cam in cameras])
    undistorted = np.stack([cam.K @ (cam.R @ points.T + cam.t[:, None]) for cam in cameras])
    undistorted = (undistorted[:, :2] / undistorted[:, 2:]).transpose(2, 0, 1)
    undistorted += rng.normal(0, 0.5, undistorted.shape)
    distorted = np.stack([cam.project(points) for cam in cameras], axis=1)

    rows = []
    baselines = ((2, "cv2.triangulatePoints per point", cv2_per_point),
                 (2, "cv2.triangulatePoints, all points in one call", cv2_all_points_at_once),
                 (4, "numpy SVD per point", svd_per_point))
    for views, name, baseline in baselines:
        px, mask = undistorted[:, :views], np.ones((args.points, views), bool)
        t_ours, ours = best_time(lambda: triangulate_dlt(P[:views], px, mask), args.repeats)  # noqa: B023
        t_base, base = best_time(lambda: baseline(P[:views], px), args.repeats)  # noqa: B023
        diff = np.abs(ours - base).max()
        assert diff < 1e-9, f"results differ by {diff} m"
        rows.append((f"DLT, {views} views", name, t_base, t_ours, diff))
    # the whole robust stage against the same function called point by point (on fewer points)
    n_loop = min(args.points, 1000)
    t_robust, out = best_time(lambda: triangulate_robust(cameras, distorted[:n_loop], 2.0), args.repeats)
    t_loop, looped = best_time(lambda: np.concatenate(
        [triangulate_robust(cameras, distorted[i:i + 1], 2.0)["points"] for i in range(n_loop)]), 1)
    diff = np.abs(out["points"] - looped).max()
    assert diff < 1e-12 and np.abs(out["points"] - points[:n_loop]).max() < 1e-6
    rows.append(("triangulate_robust, 4 views", f"same, called per point ({n_loop} points)",
                 t_loop, t_robust, diff))
    t_all, _ = best_time(lambda: triangulate_robust(cameras, distorted, 2.0), args.repeats)

    print(f"{args.points} points, best of {args.repeats} runs each (per-point robust loop: 1 run)\n")
    print("| task | baseline | baseline s | vectorised s | speed-up | max diff m |")
    print("|---|---|---:|---:|---:|---:|")
    for task, name, t_base, t_ours, diff in rows:
        print(f"| {task} | {name} | {t_base:.3f} | {t_ours:.4f} | {t_base / t_ours:.2f}x | {diff:.1e} |")
    print(f"\ntriangulate_robust on all {args.points} points (undistort, DLT, reprojection, 4 views): "
          f"{t_all:.3f} s, {1e6 * t_all / args.points:.1f} us/point")

if __name__ == "__main__":
    main()
