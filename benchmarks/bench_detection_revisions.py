"""Ball detection of this checkout beside an earlier revision's, on the same frames: speed and accuracy.

The earlier detector is `src/pingpong/perception/detection.py` as it was at `--before` (git show), loaded
as a module of its own; both run detect_stream on the same JPEG frames held in memory (reading the MCAP
is left out), `--rounds` times interleaved, and each keeps its best round, since the machine is shared
(CPU time of this process: other processes' load moves it less than wall time).
OpenCV runs on one thread, as the stage pins it. Where the stream has the twin's pixel truth (a twin
stream, or `--truth` beside an MCAP: raw/twin_truth/{session}/{cam}_ball2d.parquet), both are scored
as the perception report scores them (reports.perception_accuracy.detection_rows).

    PYTHONPATH=src python benchmarks/bench_detection_revisions.py --before HEAD~1
    PYTHONPATH=src python benchmarks/bench_detection_revisions.py --before HEAD~1 \
        --mcap RUN/raw/sessions/s02/cam2.mcap --truth RUN/raw/twin_truth/s02/cam2_ball2d.parquet --frames 4000
"""

import argparse
import time
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
from bench_detection import twin_frames
from timing import module_at

from pingpong.io.camera_streams import CameraFrame
from pingpong.io.mcap_io import read_camera_stream
from pingpong.perception import detection
from pingpong.reports.perception_accuracy import detection_rows

DETECTION = "src/pingpong/perception/detection.py"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", default="HEAD~1", help="the earlier revision")
    ap.add_argument("--mcap", type=Path)
    ap.add_argument("--truth", type=Path, help="the MCAP's pixel truth (the twin's {cam}_ball2d.parquet)")
    ap.add_argument("--frames", type=int, help="the first this many frames only")
    ap.add_argument("--rallies", type=int, default=2, help="without --mcap: a twin stream of this many")
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    cv2.setNumThreads(1)  # as pingpong.common.script.pin_threads runs the stage
    if a.mcap:
        frames = [CameraFrame(t, data) for t, data in read_camera_stream(a.mcap)]
        truth = pd.read_parquet(a.truth) if a.truth else None
        source = str(a.mcap)
    else:
        frames, truth = twin_frames(a.rallies, 480, 360)
        truth["time_ns"] = [f.time_ns for f in frames]
        source = f"twin, {a.rallies} rallies"
    frames = frames[:a.frames]
    sides = {a.before: module_at(a.before, DETECTION), "this checkout": detection}
    best, tables = dict.fromkeys(sides, np.inf), {}
    for _ in range(a.rounds):
        for name, module in sides.items():
            t0 = time.process_time()
            tables[name] = module.detect_stream(frames, module.BallDetector())
            best[name] = min(best[name], time.process_time() - t0)
    n = len(frames)
    print(f"{n} frames ({source}), best of {a.rounds} rounds\n")
    print("| detector | CPU ms/frame | time / before's |\n|---|---:|---:|")
    for name, seconds in best.items():
        print(f"| {name} | {1e3 * seconds / n:.3f} | {seconds / best[a.before]:.3f} |")
    if truth is not None:
        print("\n| detector | recall in visible frames % | median error px | false detections % of frames |\n"
              "|---|---:|---:|---:|")
        for name, found in tables.items():
            rows = [r["value"] for r in detection_rows(name, found, truth)]
            print(f"| {name} | {rows[0]:.2f} | {rows[1]:.4f} | {rows[2]:.4f} |")


if __name__ == "__main__":
    main()
