"""A camera file's frame times from its MCAP index against reading every frame, in one run.

Both sides read the same twin-like camera file (JPEG-sized frames in the chunks `CameraStreamWriter`
writes): the baseline streams every message with CRCs checked (what `read_camera_times` did before
b6e5883, and still does for files without an index), the other reads the summary and message indexes.

    PYTHONPATH=src python benchmarks/bench_camera_times.py [--frames 3000] [--frame-kb 36]
"""

import argparse
import tempfile
from pathlib import Path

import numpy as np
from timing import best_time

from pingpong.frames import FRAME_NS
from pingpong.io.mcap_io import CameraStreamWriter, _iter_messages, read_camera_times


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=3000)
    ap.add_argument("--frame-kb", type=int, default=36,
                    help="a frame's size: a twin JPEG at 480x360 is ~36 kB")
    a = ap.parse_args()
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "cam0.mcap"
        with CameraStreamWriter(path, 0, "cam0") as writer:
            for i in range(a.frames):
                writer.add(i * FRAME_NS, b"\xff\xd8" + rng.bytes(a.frame_kb * 1000) + b"\xff\xd9")

        def streamed():
            messages = _iter_messages(path, "foxglove.CompressedImage", True, "frames")
            return np.array([t for _, t, _ in messages])

        streamed_s, expected = best_time(streamed, 3)
        indexed_s, times = best_time(lambda: read_camera_times(path, strict=True), 3)
        assert np.array_equal(times, expected) and len(times) == a.frames
        size_mb = path.stat().st_size / 1e6
        print(f"| {a.frames} frames of {a.frame_kb} kB ({size_mb:.0f} MB) | s |\n|---|---:|")
        print(f"| every frame read, CRCs checked | {streamed_s:.3f} |")
        print(f"| summary and message indexes | {indexed_s:.4f} |")
        print(f"| speed-up | {streamed_s / indexed_s:.0f}x |")


if __name__ == "__main__":
    main()
