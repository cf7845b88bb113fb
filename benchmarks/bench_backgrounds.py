"""A camera job's two backgrounds (the empty lab without and with the distractor): `render_backgrounds`
against two `render_background` calls (what twin_camera did before 8ca0ce3), side by side in one run, for
each camera of the default rig at 480x360. The results must be identical.

    PYTHONPATH=src python benchmarks/bench_backgrounds.py [--repeats 3]
"""

import argparse

import numpy as np
from timing import best_time

from pingpong.common.seeding import rng_for
from pingpong.twin.render import make_lab, render_background, render_backgrounds
from pingpong.twin.rig import make_rig

SEED = 20261121  # config/config.yaml's seed: the default run's lab and rig


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args()
    cameras = make_rig(rng_for(SEED, "twin_rig"), 4, 480, 360)
    lab = make_lab(rng_for(SEED, "twin_lab"))
    print("| camera | distractor in view | two calls, s | at once, s | speed-up |\n|---|---|---:|---:|---:|")
    for camera in cameras:
        def two_calls(c=camera):
            rng = np.random.default_rng(0)
            return [render_background(c, lab, rng, intermittent=b) for b in (False, True)]

        apart_s, apart = best_time(two_calls, a.repeats)
        at_once_s, at_once = best_time(lambda c=camera: render_backgrounds(c, lab, np.random.default_rng(0)),
                                       a.repeats)
        assert all(np.array_equal(x.image, y.image) for x, y in zip(apart, at_once, strict=True))
        seen = bool((at_once[0].image != at_once[1].image).any())
        print(f"| {camera.name} | {seen} | {apart_s:.2f} | {at_once_s:.2f} | {apart_s / at_once_s:.2f}x |")


if __name__ == "__main__":
    main()
