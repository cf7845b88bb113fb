"""Rule twin_camera: one camera's stream of a session (JPEG frames in MCAP) and the ball's pixel truth."""

import logging

import pandas as pd
from tqdm import tqdm

from pingpong.common.artifacts import read_json, read_table, write_table
from pingpong.common.camera import Camera
from pingpong.common.seeding import rng_for
from pingpong.io.mcap_io import CameraStreamWriter
from pingpong.twin import truth
from pingpong.twin.cameras import frame_times, record_camera
from pingpong.twin.render import make_lab, make_player_looks, render_backgrounds


def main(ctx):
    p = ctx.params
    index = int(p["cam"].removeprefix("cam"))
    camera = Camera.from_dict(read_json(ctx.input.rig, truth.RIG)["cameras"][index])
    lab = make_lab(rng_for(p["seed"], "twin_lab"))
    rng = rng_for(p["seed"], "twin_camera", p["session"], p["cam"])
    backgrounds = render_backgrounds(camera, lab, rng)
    looks = make_player_looks(rng_for(p["seed"], "twin_looks", p["session"]), 3)
    people = read_table(ctx.input.people, truth.PEOPLE)
    frames = record_camera(camera, backgrounds, looks, read_table(ctx.input.ball, truth.BALL), people,
                           read_table(ctx.input.paddles, truth.PADDLES), rng, p["jpeg_quality"])
    rows = []
    with CameraStreamWriter(ctx.output.mcap, index, camera.name) as writer:
        for t, jpeg, row in tqdm(frames, total=len(frame_times(people)), mininterval=10):
            writer.add(t, jpeg)
            rows.append(row)
    write_table(pd.DataFrame(rows), ctx.output.ball2d, truth.BALL2D, ctx.provenance())
    logging.info("%s %s: %d frames", p["session"], p["cam"], len(rows))
