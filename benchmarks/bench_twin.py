"""The twin's camera writing speed (render + JPEG + MCAP) against JPEG encoding alone, in one run.

Both sides work on the same frames of one simulated session: the baseline encodes frames that were
rendered beforehand, so the ratio says what rendering and writing cost on top of the encoding that
any recorder pays.

    PYTHONPATH=src python benchmarks/bench_twin.py [--rallies 2] [--width 480] [--height 360]
"""

import argparse
import itertools
import tempfile
import time
from pathlib import Path

from pingpong.common.seeding import rng_for
from pingpong.io.mcap_io import CameraStreamWriter
from pingpong.twin.cameras import record_camera
from pingpong.twin.render import encode_jpeg, make_lab, make_player_looks, render_backgrounds, render_frame
from pingpong.twin.rig import make_rig
from pingpong.twin.session import FaultRates, simulate_session


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rallies", type=int, default=2)
    ap.add_argument("--width", type=int, default=480)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--frames", type=int, default=800)
    a = ap.parse_args()
    truth = simulate_session(a.rallies, FaultRates(), rng_for(1, "bench"))
    camera = make_rig(rng_for(1, "rig"), 4, a.width, a.height)[0]
    lab = make_lab(rng_for(1, "lab"))
    rng = rng_for(1, "cam")
    backgrounds = render_backgrounds(camera, lab, rng)
    looks = make_player_looks(rng, 3)

    # baseline: JPEG encoding of the same number of already-rendered frames
    image, _ = render_frame(backgrounds[0], camera, None, [], [], rng)
    images = [image.copy() for _ in range(a.frames)]
    t0 = time.perf_counter()
    for im in images:
        encode_jpeg(im)
    encode_s = time.perf_counter() - t0

    with tempfile.TemporaryDirectory() as tmp:
        frames = record_camera(camera, backgrounds, looks, truth.ball, truth.people, truth.paddles, rng, 90)
        t0 = time.perf_counter()
        with CameraStreamWriter(Path(tmp) / "cam0.mcap", 0, camera.name) as writer:
            n = 0
            for t, jpeg, _ in itertools.islice(frames, a.frames):
                writer.add(t, jpeg)
                n += 1
        write_s = time.perf_counter() - t0
    print(f"| {a.width}x{a.height} | frames/s |\n|---|---:|")
    print(f"| JPEG encoding alone | {a.frames / encode_s:.0f} |")
    print(f"| twin camera writing (render + JPEG + MCAP) | {n / write_s:.0f} |")
    ratio = (write_s / n) / (encode_s / a.frames)
    print(f"| ratio (writing / encoding time per frame) | {ratio:.1f}x |")


if __name__ == "__main__":
    main()
