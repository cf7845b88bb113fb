"""The OpenPose twin's occlusion test as it ran before 7cd0a29 (squared pixel offsets summed over a last
axis of 2) against `openpose_sim._occluded` (x and y apart), in one run, on the same projected joints.

Both sides take one session's people as one camera sees them; the results must be identical.

    PYTHONPATH=src python benchmarks/bench_occlusion.py [--rallies 4]
"""

import argparse

import numpy as np
from timing import best_time

from pingpong.common.seeding import rng_for
from pingpong.twin import truth as twin_truth
from pingpong.twin.openpose_sim import OCCLUDER_RADIUS, _occluded
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


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rallies", type=int, default=4)
    a = ap.parse_args()
    session = simulate_session(a.rallies, FaultRates(), rng_for(1, "bench"))
    camera = make_rig(rng_for(1, "rig"), 4, 480, 360)[2]
    joints = np.stack([rows[list(twin_truth.JOINT_COLUMNS)].to_numpy().reshape(-1, 25, 3)
                       for _, rows in session.people.groupby("person", sort=False)])
    n_people, n = joints.shape[:2]
    flat = np.nan_to_num(joints).reshape(-1, 3)
    px = camera.project(flat).reshape(n_people, n, 25, 2)
    depth = camera.depth(flat).reshape(n_people, n, 25)
    absent = np.isnan(joints).all(axis=(-1, -2))
    px[absent], depth[absent] = np.nan, np.nan

    summed_s, before = best_time(lambda: occluded_summed(px, depth, camera.K[0, 0]), 3)
    apart_s, now = best_time(lambda: _occluded(px, depth, camera.K[0, 0]), 3)
    assert np.array_equal(before, now), "the two occlusion tests disagree"
    print(f"| {n_people} people x {n} frames, 480x360 | s |\n|---|---:|")
    print(f"| offsets squared and summed over the last axis (before 7cd0a29) | {summed_s:.3f} |")
    print(f"| x and y apart (now) | {apart_s:.3f} |")
    print(f"| speed-up | {summed_s / apart_s:.1f}x |")


if __name__ == "__main__":
    main()
