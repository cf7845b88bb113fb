"""The twin's OpenPose simulation over many frames at once against one frame at a time, in one run; and
its occlusion test against the one before 7cd0a29.

Both sides simulate the same frames of one session's people for one camera: the baseline calls
`simulate_openpose` per frame (the per-frame loop `twin_openpose` ran before f461718), the other
`simulate_openpose_frames` on chunks of frames as the rule does now. The occlusion test (`_occluded`,
x and y apart) runs beside the one it replaced (squared offsets summed over a last axis of 2) on the
same projected joints; the results must be identical.

    PYTHONPATH=src python benchmarks/bench_openpose.py [--rallies 4] [--chunk 2000]
"""

import argparse

import numpy as np
from timing import best_time

from pingpong.common.seeding import rng_for
from pingpong.twin import truth as twin_truth
from pingpong.twin.openpose_sim import (
    OCCLUDER_RADIUS,
    _occluded,
    default_keypoint_errors,
    projected_people,
    simulate_openpose,
    simulate_openpose_frames,
)
from pingpong.twin.rig import make_rig
from pingpong.twin.session import FaultRates, simulate_session


def occluded_summed(px: np.ndarray, depth: np.ndarray, f: float) -> np.ndarray:
    """The baseline: _occluded before 7cd0a29."""
    hidden = np.zeros(depth.shape, bool)
    with np.errstate(invalid="ignore", divide="ignore"):
        width2 = (f * OCCLUDER_RADIUS / depth) ** 2
        for i in range(len(px)):
            for k in range(len(px)):
                if k != i:
                    dist2 = ((px[i][:, :, None] - px[k][:, None]) ** 2).sum(axis=-1)
                    covers = (dist2 < width2[k][:, None]) & (depth[k][:, None] < depth[i][:, :, None]) \
                        & (depth[k][:, None] > 0.1)
                    hidden[i] |= covers.any(axis=2)
    return hidden


def compare_occlusion(camera, bodies: np.ndarray) -> None:
    n_people, n = bodies.shape[:2]
    _, px, depth = projected_people(camera, bodies)
    summed_s, before = best_time(lambda: occluded_summed(px, depth, camera.K[0, 0]), 3)
    apart_s, now = best_time(lambda: _occluded(px, depth, camera.K[0, 0]), 3)
    assert np.array_equal(before, now), "the two occlusion tests disagree"
    print(f"\n| occlusion test, {n_people} people x {n} frames | s |\n|---|---:|")
    print(f"| offsets squared and summed over the last axis (before 7cd0a29) | {summed_s:.3f} |")
    print(f"| x and y apart (now) | {apart_s:.3f} |")
    print(f"| speed-up | {summed_s / apart_s:.1f}x |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rallies", type=int, default=4)
    ap.add_argument("--chunk", type=int, default=2000)
    a = ap.parse_args()
    session = simulate_session(a.rallies, FaultRates(), rng_for(1, "bench"))
    camera = make_rig(rng_for(1, "rig"), 4, 480, 360)[2]
    bodies = np.stack([rows[list(twin_truth.JOINT_COLUMNS)].to_numpy().reshape(-1, 25, 3)
                       for _, rows in session.people.groupby("person", sort=False)])
    n = bodies.shape[1]

    def one_at_a_time():
        rng = np.random.default_rng(0)
        return [simulate_openpose(camera, [b for b in bodies[:, f] if not np.isnan(b).all()], rng,
                                  default_keypoint_errors())
                for f in range(n)]

    def chunked():
        rng = np.random.default_rng(0)
        return [people for first in range(0, n, a.chunk)
                for people in simulate_openpose_frames(camera, bodies[:, first:first + a.chunk], rng,
                                                                 default_keypoint_errors())]

    per_frame_s, one = best_time(one_at_a_time, 3)
    chunked_s, many = best_time(chunked, 3)
    assert len(many) == len(one) == n
    print(f"| {n} frames, 480x360 | frames/s |\n|---|---:|")
    print(f"| one frame at a time | {n / per_frame_s:.0f} |")
    print(f"| {a.chunk} frames at once | {n / chunked_s:.0f} |")
    print(f"| speed-up | {per_frame_s / chunked_s:.1f}x |")
    compare_occlusion(camera, bodies)


if __name__ == "__main__":
    main()
