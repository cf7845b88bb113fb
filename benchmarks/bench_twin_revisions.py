"""The twin camera's per-frame path of this checkout beside an earlier revision's: speed, and the same bytes.

The earlier renderer is `src/pingpong/twin/render.py` as it was at `--before` (git show), loaded as a
module of its own; both turn the same session's people, paddles and ball into frames (frame_shapes,
render_shapes with the sensor noise of one seeded rng each, encode_jpeg) over the same backgrounds,
`--rounds` times interleaved, and each keeps its best round of CPU time (the machine is shared). The
JPEG bytes and ball truth of every frame must be equal: a speed-up that changes a byte is refused.

    PYTHONPATH=src python benchmarks/bench_twin_revisions.py --before HEAD~1 [--cameras 0 1 2 3]
"""

import argparse
import hashlib
import time

import cv2
import numpy as np
from timing import module_at

from pingpong.common.seeding import rng_for
from pingpong.twin import cameras, render
from pingpong.twin.rig import make_rig
from pingpong.twin.session import SIDES, FaultRates, simulate_session
from pingpong.twin.truth import JOINT_COLUMNS

RENDER = "src/pingpong/twin/render.py"


def frame_inputs(truth, camera, n_frames: int):
    """What record_camera hands the renderer per frame, for the first n_frames camera frames."""
    times = cameras.frame_times(truth.people)[:n_frames]
    offsets = np.linspace(-cameras.EXPOSURE_NS / 2, cameras.EXPOSURE_NS / 2, cameras.EXPOSURE_SAMPLES)
    exposure = cameras.ball_positions_at(truth.ball, (times[:, None] + offsets.astype(np.int64)).ravel())
    exposure = exposure.reshape(len(times), cameras.EXPOSURE_SAMPLES, 3)
    bodies = {p: rows[list(JOINT_COLUMNS)].to_numpy().reshape(-1, 25, 3)[:n_frames]
              for p, rows in truth.people.groupby("person", sort=False)}
    pads = cameras._paddles_at(truth.paddles, times)
    persons = list(SIDES.values()) + ["bystander"]
    return times, exposure, [bodies[p] for p in persons], [pads[p] for p in SIDES.values()]


def record(module, camera, backgrounds, looks, inputs, seed: int) -> tuple[float, str, int]:
    """CPU seconds, a digest of every frame's JPEG and ball truth, frames: the module's per-frame path."""
    times, exposure, bodies, pads = inputs
    rng, digest = np.random.default_rng(seed), hashlib.sha256()
    t0 = time.process_time()
    for first in range(0, len(times), cameras.SHAPE_CHUNK):
        chunk = slice(first, first + cameras.SHAPE_CHUNK)
        shapes = module.frame_shapes(camera, [b[chunk] for b in bodies], looks,
                                     [(p[chunk], r[chunk]) for p, r in pads])
        for i, frame in enumerate(shapes, start=first):
            balls = exposure[i][np.isfinite(exposure[i]).all(axis=1)]
            background = backgrounds[int((times[i] // cameras.DISTRACTOR_PERIOD_NS) % 2)]
            image, truth = module.render_shapes(background, camera, balls if len(balls) else None, frame, rng)
            digest.update(module.encode_jpeg(image, 90))
            digest.update(np.array([*truth.pixel, truth.visibility, truth.radius_px]).tobytes())
    return time.process_time() - t0, digest.hexdigest(), len(times)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", default="HEAD~1", help="the earlier revision")
    ap.add_argument("--rallies", type=int, default=3)
    ap.add_argument("--frames", type=int, default=2500)
    ap.add_argument("--cameras", type=int, nargs="+", default=[0])
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    cv2.setNumThreads(1)  # as pingpong.common.script.pin_threads runs the stage
    truth = simulate_session(a.rallies, FaultRates(), rng_for(1, "bench"))
    rig = make_rig(rng_for(1, "rig"), 4, 480, 360)
    lab = render.make_lab(rng_for(1, "lab"))
    sides = {a.before: module_at(a.before, RENDER), "this checkout": render}
    print(f"{a.rallies} rallies, 480x360, best of {a.rounds} rounds\n")
    print("| camera | frames | renderer | CPU ms/frame | time / before's | JPEG and truth digest |\n"
          "|---|---:|---|---:|---:|---|")
    for index in a.cameras:
        camera = rig[index]
        backgrounds = render.render_backgrounds(camera, lab, rng_for(1, "cam", index))
        looks = render.make_player_looks(rng_for(1, "looks"), 3)
        inputs = frame_inputs(truth, camera, a.frames)
        best, digests = dict.fromkeys(sides, np.inf), {}
        for _ in range(a.rounds):
            for name, module in sides.items():
                seconds, digests[name], n = record(module, camera, backgrounds, looks, inputs, index)
                best[name] = min(best[name], seconds)
        for name, seconds in best.items():
            print(f"| cam{index} | {n} | {name} | {1e3 * seconds / n:.3f} | {seconds / best[a.before]:.3f} "
                  f"| {digests[name][:16]} |")
        if len(set(digests.values())) != 1:
            raise SystemExit(f"cam{index}: the frames differ from {a.before}'s")


if __name__ == "__main__":
    main()
