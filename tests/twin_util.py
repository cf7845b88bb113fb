"""A twin camera's stream made in-process, for the detector tests."""

import pandas as pd

from pingpong.common.seeding import rng_for
from pingpong.io.camera_streams import CameraFrame
from pingpong.twin import render
from pingpong.twin.cameras import record_camera
from pingpong.twin.rig import make_rig
from pingpong.twin.session import FaultRates, simulate_session


def twin_stream(seed: int = 5, rallies: int = 2, width: int = 480, height: int = 360):
    """Camera 0's frames (CameraFrame, JPEG q90, 100 Hz) of a twin session and its ball truth per frame.

    One background, with the sometimes-present ball bucket: a session this short stays in the first of the
    twin's 20 s distractor periods anyway, and rendering the lab twice would double the setup."""
    truth = simulate_session(rallies, FaultRates(), rng_for(seed, "session"))
    camera = make_rig(rng_for(seed, "rig"), 4, width, height)[0]
    rng = rng_for(seed, "camera")
    lab = render.make_lab(rng_for(seed, "lab"))
    background = render.render_background(camera, lab, rng, intermittent=True)
    looks = render.make_player_looks(rng, 3)
    frames, rows = [], []
    for t, jpeg, row in record_camera(camera, (background, background), looks, truth.ball, truth.people,
                                      truth.paddles, rng, 90):
        frames.append(CameraFrame(t, jpeg))
        rows.append(row)
    return frames, pd.DataFrame(rows)
