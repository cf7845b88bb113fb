"""Ball detection speed against JPEG decoding alone, today's full-resolution detector beside the reduced one.

All variants work on the same JPEG frames held in memory (MCAP reading is left out), as CameraFrame:
decoding only (cv2.imdecode of the full frame: the bar), the same through pingpong.io.jpeg.decode_jpeg
(its fd 2 capture), the full-resolution detector (detect_stream with reduction=1: today's detector, and
still the default at 480x360), the default (detect_stream, the reduction from the image width: 2 at
1440x1080), the default on frames that can only decode whole (no CameraFrame.decode_rows: a tracked
ball's window rows are then not decoded alone), and detection searching the whole full frame every
time. Each variant runs `--rounds`
times, interleaved, and keeps its best round, since the machine is shared; OpenCV runs on one thread,
as the stage pins it.

On a twin stream it also scores both detectors against the twin's pixel truth (visibility >= 0.5; a
detection counts within 5 px at 480 wide, scaled with the width), and it checks whether the default's
detections equal the full-resolution detector's, as they must at 480x360.

    PYTHONPATH=src python benchmarks/bench_detection.py [--mcap raw/sessions/s00/cam0.mcap] [--rallies 2]
    PYTHONPATH=src python benchmarks/bench_detection.py --mcap none --width 1440 --height 1080 --rallies 2

Without --mcap (or when the file is absent) it uses /tmp/sample_raw/sessions/s00/cam0.mcap when there,
else a stream of the twin (`--rallies` rallies, one camera, `--width` x `--height`).
"""

import argparse
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import pandas as pd

from pingpong.common.seeding import rng_for
from pingpong.io.camera_streams import CameraFrame
from pingpong.io.jpeg import decode_jpeg
from pingpong.io.mcap_io import read_camera_stream
from pingpong.perception.detection import BallDetector, detect_ball, detect_stream, stream_reduction
from pingpong.twin import render
from pingpong.twin.cameras import record_camera
from pingpong.twin.rig import make_rig
from pingpong.twin.session import FaultRates, simulate_session

SAMPLE = Path("/tmp/sample_raw/sessions/s00/cam0.mcap")
VISIBLE = 0.5  # visibility from which a ball counts as visible (tests/test_detection.py)
FALSE_PX_AT_480 = 5.0  # a detection further than this (scaled with the width) from the truth is false


def twin_frames(rallies: int, width: int, height: int) -> tuple[list[CameraFrame], pd.DataFrame]:
    """One camera's frames of a twin session and its ball truth (u, v, visibility per frame)."""
    truth = simulate_session(rallies, FaultRates(), rng_for(1, "bench"))
    camera = make_rig(rng_for(1, "rig"), 4, width, height)[0]
    rng = rng_for(1, "cam")
    lab = render.make_lab(rng_for(1, "lab"))
    backgrounds = render.render_backgrounds(camera, lab, rng)
    looks = render.make_player_looks(rng, 3)
    frames, rows = [], []
    for t, jpeg, row in record_camera(camera, backgrounds, looks, truth.ball, truth.people, truth.paddles,
                                      rng, 90):
        frames.append(CameraFrame(t, jpeg))
        rows.append(row)
    return frames, pd.DataFrame(rows)


def decode_only(frames, detector):
    for frame in frames:
        cv2.imdecode(np.frombuffer(frame.data, np.uint8), cv2.IMREAD_COLOR)


def decode_capturing(frames, detector):
    for frame in frames:
        decode_jpeg(frame.data)


def full_resolution(frames, detector):
    return detect_stream(frames, detector, reduction=1)


def reduced(frames, detector):
    return detect_stream(frames, detector)


@dataclass(frozen=True)
class WholeFrame:
    """A frame without decode_rows: every decode is of the whole image."""

    time_ns: int
    data: bytes

    def decode(self, reduction: int = 1):
        return decode_jpeg(self.data, reduction)


def whole_images(frames, detector):
    return detect_stream([WholeFrame(f.time_ns, f.data) for f in frames], detector)


def full_frame_every_frame(frames, detector):
    for frame in frames:
        detect_ball(frame.decode(1)[0], detector)


def score(found: pd.DataFrame, truth: pd.DataFrame, width: int) -> dict:
    """Recall (%), median and p95 centre error (px) of the visible balls, false detections (%)."""
    error = np.hypot(found["u"] - truth["u"], found["v"] - truth["v"]).to_numpy()
    visible = truth["visibility"].to_numpy() >= VISIBLE
    near = found["detected"].to_numpy() & (error <= FALSE_PX_AT_480 * width / 480)
    false = found["detected"].to_numpy() & ~near & (truth["visibility"].to_numpy() < VISIBLE)
    hits = error[visible & near]
    return {"visible": int(visible.sum()), "recall %": 100 * near[visible].mean(),
            "median px": np.median(hits), "p95 px": np.percentile(hits, 95), "false %": 100 * false.mean()}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mcap", type=Path, default=SAMPLE)
    ap.add_argument("--rallies", type=int, default=2)
    ap.add_argument("--width", type=int, default=480)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    cv2.setNumThreads(1)  # as pingpong.common.script.pin_threads runs the stage
    truth = None
    if a.mcap.is_file():
        frames, source = [CameraFrame(t, data) for t, data in read_camera_stream(a.mcap)], str(a.mcap)
    else:
        (frames, truth), source = twin_frames(a.rallies, a.width, a.height), f"twin, {a.rallies} rallies"
    height, width = frames[0].decode(1)[0].shape[:2]
    detector = BallDetector()
    variants = {"decode only (cv2.imdecode, full frame)": decode_only,
                "decode only (decode_jpeg: fd 2 captured)": decode_capturing,
                "full-resolution detector (detect_stream, reduction=1)": full_resolution,
                f"detect_stream default (reduction {stream_reduction(width)} at this width)": reduced,
                "detect_stream default, frames that decode only whole": whole_images,
                "decode + detect, full frame every frame": full_frame_every_frame}
    best = dict.fromkeys(variants, np.inf)
    tables = {}
    for _ in range(a.rounds):
        for name, run in variants.items():
            t0 = time.perf_counter()
            tables[name] = run(frames, detector)
            best[name] = min(best[name], time.perf_counter() - t0)
    n = len(frames)
    decode_s = best["decode only (cv2.imdecode, full frame)"]
    print(f"{n} frames {width}x{height} ({source}), best of {a.rounds} rounds\n")
    print("| variant | frames/s | ms/frame | frames/s / decode only's |\n|---|---:|---:|---:|")
    for name, seconds in best.items():
        print(f"| {name} | {n / seconds:.0f} | {1e3 * seconds / n:.2f} | {decode_s / seconds:.2f} |")
    full, stage = tables[list(variants)[2]], tables[list(variants)[3]]
    print(f"\ndefault detections equal the full-resolution detector's: {stage.equals(full)}, "
          f"the whole images': {stage.equals(tables[list(variants)[4]])}")
    if truth is not None:
        print("\n| detector | visible balls | recall % | median error px | p95 error px | false % |\n"
              "|---|---:|---:|---:|---:|---:|")
        for name, found in (("full resolution (today's)", full), ("default", stage)):
            s = score(found, truth, width)
            print(f"| {name} | {s['visible']} | {s['recall %']:.2f} | {s['median px']:.3f} | "
                  f"{s['p95 px']:.3f} | {s['false %']:.2f} |")


if __name__ == "__main__":
    main()
