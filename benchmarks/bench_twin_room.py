"""The club room's cost (config twin.room): CPU time a frame of one camera's rendering + JPEG encoding, with
every room feature on (config/config.yaml's twin.room) and off, side by side on the same session and camera.

CPU time (time.process_time) of record_room_camera's loop, which renders and encodes each frame; the
backgrounds are rendered before the clock starts (once per camera in the pipeline, not per frame). Each
side runs `--repeats` times, alternating, and the median is reported: the machine is shared.

    PYTHONPATH=src python benchmarks/bench_twin_room.py [--frames 600] [--repeats 3] [--camera 0]
"""

import argparse
import itertools
import statistics
import time

import yaml

from pingpong.common.seeding import rng_for
from pingpong.twin import render, room
from pingpong.twin.cameras import record_room_camera
from pingpong.twin.rig import make_rig
from pingpong.twin.session import FaultRates, simulate_session

ROOM_YAML = "config/config.yaml"  # the default run's room


def cpu_ms_per_frame(session, camera, features: room.Room, frames: int, seed: int = 1) -> float:
    """CPU ms a frame of rendering + JPEG over the first `frames` frames of one camera."""
    lab = room.room_lab(render.make_lab(rng_for(seed, "lab")), features, rng_for(seed, "room"))
    rng = rng_for(seed, "camera")
    backgrounds = render.render_backgrounds(camera, lab, rng)
    looks = room.dress_bystander(render.make_player_looks(rng, 3), features)
    stream = record_room_camera(camera, backgrounds, looks, session.ball, session.people, session.paddles,
                                rng, 90, features, rng_for(seed, "room", "session"),
                                rng_for(seed, "room", "camera"))
    t0 = time.process_time()
    n = sum(1 for _ in itertools.islice(stream, frames))
    return (time.process_time() - t0) / n * 1e3


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=600)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--camera", type=int, default=0)
    ap.add_argument("--width", type=int, default=480)
    ap.add_argument("--height", type=int, default=360)
    a = ap.parse_args()
    with open(ROOM_YAML) as f:
        features = room.Room.from_config(yaml.safe_load(f)["twin"]["room"])
    session = simulate_session(2, FaultRates(), rng_for(1, "bench"))
    camera = make_rig(rng_for(1, "rig"), 4, a.width, a.height)[a.camera]
    times = {"off": [], "on": []}
    for _ in range(a.repeats):
        for side, feats in (("off", room.Room()), ("on", features)):
            times[side].append(cpu_ms_per_frame(session, camera, feats, a.frames))
    off, on = statistics.median(times["off"]), statistics.median(times["on"])
    print(f"| {a.width}x{a.height}, camera {a.camera}, {a.frames} frames "
          f"| CPU ms/frame (median of {a.repeats}) | runs |\n|---|---:|---|")
    for side, value in (("room off", off), ("room on", on)):
        runs = ", ".join(f"{t:.2f}" for t in times[side.split()[1]])
        print(f"| {side} | {value:.2f} | {runs} |")
    print(f"| the room's extra | {on - off:.2f} | |")


if __name__ == "__main__":
    main()
