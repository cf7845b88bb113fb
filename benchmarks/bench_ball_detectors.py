"""Frames per second of the two ball detectors, colour (detection.detect_stream, the paper's) and track
(ball_track.detect_stream with its scene image, as the detection stage runs it), decoding included.

Each size's frames are one twin camera's JPEG frames (q90, `--rallies` rallies, 100 Hz) held in memory
as CameraFrame (MCAP reading is left out; the stage reads the same frames from the file), or a recorded
stream (`--stream`: any file pingpong.io.camera_streams reads, e.g. an H.264 video decoded by PyAV; its
frames are read once into memory). The methods run `--rounds` times interleaved (colour, track, colour,
...), each keeping its best round, as the machine is shared; OpenCV runs on one thread, as the stage pins
it, so frames/s is per core. On the twin it also scores both against the truth (tests/test_detection.py's
scoring: recall of visible balls within 5 px at 480 wide, scaled with the width; false: detections farther
or with no visible ball).

With `--against REV` the track method of git revision REV (its ball_track.py and detection.py, loaded
beside this tree's) runs in the same rounds, as the baseline of a change to the track method: its
frames/s and whether its detections are this tree's, value for value.

    PYTHONPATH=src python benchmarks/bench_ball_detectors.py [--sizes 480x360 1280x720] [--rallies 2]
    PYTHONPATH=src python benchmarks/bench_ball_detectors.py --stream raw/sessions/s00/cam0.mcap
    PYTHONPATH=src python benchmarks/bench_ball_detectors.py --sizes 480x360 --against 6fb8228
"""

import argparse
import subprocess
import sys
import time
import types
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
from bench_detection import twin_frames  # the same stream: seed 1, camera 0

from pingpong.io.camera_streams import open_camera_stream
from pingpong.perception import ball_track, detection

VISIBLE = 0.5
FALSE_PX_AT_480 = 5.0


def colour(frames, detector):
    return detection.detect_stream(frames, detector)


def track(frames, detector, module=ball_track):
    return module.detect_stream(frames, detector, module.TrackSettings(), module.scene_for(frames))[0]


def track_at(revision: str):
    """The track method of a git revision: its ball_track and detection modules, loaded under their own
    names beside this tree's (the baseline of a change)."""
    root = Path(__file__).resolve().parents[1]

    def load(name: str, path: str, imports=()):
        source = subprocess.run(["git", "-C", str(root), "show", f"{revision}:{path}"], check=True,
                                capture_output=True, text=True).stdout
        for old, new in imports:
            source = source.replace(old, new)
        module = sys.modules[name] = types.ModuleType(name)
        exec(compile(source, f"{revision}:{path}", "exec"), module.__dict__)
        return module

    load("baseline_detection", "src/pingpong/perception/detection.py")
    module = load("baseline_ball_track", "src/pingpong/perception/ball_track.py",
                  [("from pingpong.perception import detection\n",
                    "import baseline_detection as detection\n"),
                   ("from pingpong.perception.detection import", "from baseline_detection import")])
    return lambda frames, detector: track(frames, detector, module)


def score(found: pd.DataFrame, truth: pd.DataFrame, width: int) -> tuple[float, float]:
    """(recall %, false %) of a detections table against the twin's truth."""
    error = np.hypot(found["u"] - truth["u"], found["v"] - truth["v"]).to_numpy()
    visibility = truth["visibility"].to_numpy()
    near = found["detected"].to_numpy() & (error <= FALSE_PX_AT_480 * width / 480)
    false = found["detected"].to_numpy() & ((visibility == 0) | ~near)
    return 100 * near[visibility >= VISIBLE].mean(), 100 * false.mean()


def measure(frames, truth, source: str, rounds: int, against: str | None = None) -> None:
    detector = detection.BallDetector()
    height, width = frames[0].decode(1)[0].shape[:2]
    methods = {"colour": colour, "track": track}
    if against:
        methods[f"track@{against}"] = track_at(against)
    best, tables = dict.fromkeys(methods, np.inf), {}
    for _ in range(rounds):
        for name, run in methods.items():
            start = time.perf_counter()
            tables[name] = run(frames, detector)
            best[name] = min(best[name], time.perf_counter() - start)
    n = len(frames)
    print(f"\n{n} frames {width}x{height} ({source}), best of {rounds} interleaved rounds, one thread\n")
    print("| method | frames/s | ms/frame | frames/s / colour's | recall % | false % |\n"
          "|---|---:|---:|---:|---:|---:|")
    for name, seconds in best.items():
        recall, false = score(tables[name], truth, width) if truth is not None else (np.nan, np.nan)
        print(f"| {name} | {n / seconds:.0f} | {1e3 * seconds / n:.2f} | {best['colour'] / seconds:.2f} | "
              f"{recall:.2f} | {false:.3f} |")
    if against:
        same = tables["track"].equals(tables[f"track@{against}"])
        print(f"\ntrack / track@{against}: {best[f'track@{against}'] / best['track']:.2f}x the frames/s; "
              f"detections {'identical' if same else 'DIFFERENT'}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", nargs="+", default=["480x360", "1280x720"])
    ap.add_argument("--rallies", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--stream", help="a recorded stream instead of the twin")
    ap.add_argument("--against", help="a git revision whose track method runs beside this one (a baseline)")
    a = ap.parse_args()
    cv2.setNumThreads(1)  # as pingpong.common.script.pin_threads runs the stage
    if a.stream:
        _, frames = open_camera_stream(a.stream)
        measure(list(frames), None, a.stream, a.rounds, a.against)
        return
    for size in a.sizes:
        width, height = (int(x) for x in size.split("x"))
        frames, truth = twin_frames(a.rallies, width, height)
        measure(frames, truth, f"twin, {a.rallies} rallies", a.rounds, a.against)


if __name__ == "__main__":
    main()
