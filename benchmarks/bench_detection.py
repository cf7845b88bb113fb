"""Ball detection speed against JPEG decoding alone and against full-frame search, in one run.

All variants work on the same JPEG frames held in memory (MCAP reading is left out): decoding only
(cv2.imdecode), decoding + detection as the stage runs it (detect_stream: search window around the
previous detection), and decoding + detection searching the whole frame every time. Each variant runs
`--rounds` times, interleaved, and keeps its best round, since the machine is shared.

    PYTHONPATH=src python benchmarks/bench_detection.py [--mcap raw/sessions/s00/cam0.mcap] [--rallies 2]

Without --mcap (or when the file is absent) it uses /tmp/sample_raw/sessions/s00/cam0.mcap when there,
else a stream of the twin (`--rallies` rallies, one camera, `--width` x `--height`).
"""

import argparse
import time
from pathlib import Path

import cv2
import numpy as np

from pingpong.common.seeding import rng_for
from pingpong.io.mcap_io import read_camera_stream
from pingpong.perception.detection import BallDetector, detect_ball, detect_stream
from pingpong.twin import render
from pingpong.twin.cameras import record_camera
from pingpong.twin.rig import make_rig
from pingpong.twin.session import FaultRates, simulate_session

SAMPLE = Path("/tmp/sample_raw/sessions/s00/cam0.mcap")


def twin_frames(rallies: int, width: int, height: int) -> list[tuple[int, bytes]]:
    truth = simulate_session(rallies, FaultRates(), rng_for(1, "bench"))
    camera = make_rig(rng_for(1, "rig"), 4, width, height)[0]
    rng = rng_for(1, "cam")
    lab = render.make_lab(rng_for(1, "lab"))
    backgrounds = tuple(render.render_background(camera, lab, rng, intermittent=b) for b in (False, True))
    looks = render.make_player_looks(rng, 3)
    return [(t, jpeg) for t, jpeg, _ in record_camera(camera, backgrounds, looks, truth.ball, truth.people,
                                                      truth.paddles, rng, 90)]


def decode_only(frames, detector):
    for _, jpeg in frames:
        cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)


def decode_detect_windowed(frames, detector):
    detect_stream(frames, detector)


def decode_detect_full_frame(frames, detector):
    for _, jpeg in frames:
        detect_ball(cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR), detector)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mcap", type=Path, default=SAMPLE)
    ap.add_argument("--rallies", type=int, default=2)
    ap.add_argument("--width", type=int, default=480)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    if a.mcap.is_file():
        frames, source = list(read_camera_stream(a.mcap)), str(a.mcap)
    else:
        frames, source = twin_frames(a.rallies, a.width, a.height), f"twin, {a.rallies} rallies"
    height, width = cv2.imdecode(np.frombuffer(frames[0][1], np.uint8), cv2.IMREAD_COLOR).shape[:2]
    detector = BallDetector()
    variants = {"decode only (cv2.imdecode)": decode_only,
                "decode + detect, search window (detect_stream)": decode_detect_windowed,
                "decode + detect, full frame every frame": decode_detect_full_frame}
    best = dict.fromkeys(variants, np.inf)
    for _ in range(a.rounds):
        for name, run in variants.items():
            t0 = time.perf_counter()
            run(frames, detector)
            best[name] = min(best[name], time.perf_counter() - t0)
    n = len(frames)
    decode_s, windowed_s, full_s = best.values()
    print(f"{n} frames {width}x{height} ({source}), best of {a.rounds} rounds\n")
    print("| variant | frames/s | ms/frame | time / decode only |\n|---|---:|---:|---:|")
    for name, seconds in best.items():
        print(f"| {name} | {n / seconds:.0f} | {1e3 * seconds / n:.2f} | {seconds / decode_s:.2f} |")
    print(f"\ndetection alone: {1e3 * (windowed_s - decode_s) / n:.3f} ms/frame with the window, "
          f"{1e3 * (full_s - decode_s) / n:.3f} ms/frame full frame; "
          f"full frame / window (detection alone): {(full_s - decode_s) / (windowed_s - decode_s):.1f}x")


if __name__ == "__main__":
    main()
