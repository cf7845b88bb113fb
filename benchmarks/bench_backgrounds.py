"""A camera job's two backgrounds (the empty lab without and with the distractor): `render_backgrounds`
against two `render_background` calls (what twin_camera did before 8ca0ce3), side by side in one run, for
each camera of the default run's rig (config/config.yaml). The results must be identical.

    PYTHONPATH=src python benchmarks/bench_backgrounds.py [--repeats 3]
"""

import argparse
from pathlib import Path

import numpy as np
import yaml
from timing import best_time

from pingpong.common.config import validate_config
from pingpong.common.seeding import rng_for
from pingpong.twin.render import make_lab, render_background, render_backgrounds
from pingpong.twin.rig import make_rig

CONFIG = Path(__file__).resolve().parents[1] / "config"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args()
    config = validate_config(yaml.safe_load((CONFIG / "config.yaml").read_text()), CONFIG / "schema.yaml")
    twin = config["twin"]
    cameras = make_rig(rng_for(config["seed"], "twin_rig"), twin["n_cameras"], twin["width"], twin["height"])
    lab = make_lab(rng_for(config["seed"], "twin_lab"))
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
