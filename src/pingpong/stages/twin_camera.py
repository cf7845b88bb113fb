"""Rule twin_camera: one camera's stream of a session (JPEG frames in MCAP) and the ball's pixel truth.

With config twin.room's ball features on (pingpong.twin.room), also the other balls' truth
(raw/twin_truth/{session}/{cam}_other_balls2d.parquet, output `other_balls`).
"""

import logging

import pandas as pd
from tqdm import tqdm

from pingpong.common.artifacts import read_json, read_table, write_table
from pingpong.common.camera import Camera
from pingpong.common.seeding import rng_for
from pingpong.io.mcap_io import CameraStreamWriter
from pingpong.twin import truth
from pingpong.twin.cameras import frame_times, record_room_camera
from pingpong.twin.render import make_lab, make_player_looks, render_backgrounds
from pingpong.twin.room import Room, dress_bystander, room_lab


def main(ctx):
    p = ctx.params
    index = int(p["cam"].removeprefix("cam"))
    camera = Camera.from_dict(read_json(ctx.input.rig, truth.RIG)["cameras"][index])
    room = Room.from_config(p["room"])
    lab = room_lab(make_lab(rng_for(p["seed"], "twin_lab")), room, rng_for(p["seed"], "twin_room"))
    rng = rng_for(p["seed"], "twin_camera", p["session"], p["cam"])
    backgrounds = render_backgrounds(camera, lab, rng)
    looks = dress_bystander(make_player_looks(rng_for(p["seed"], "twin_looks", p["session"]), 3), room)
    people = read_table(ctx.input.people, truth.PEOPLE)
    frames = record_room_camera(camera, backgrounds, looks, read_table(ctx.input.ball, truth.BALL), people,
                                read_table(ctx.input.paddles, truth.PADDLES), rng, p["jpeg_quality"], room,
                                rng_for(p["seed"], "twin_room", p["session"]),
                                rng_for(p["seed"], "twin_room_gain", p["session"], p["cam"]))
    rows, other_rows = [], []
    with CameraStreamWriter(ctx.output.mcap, index, camera.name) as writer:
        for t, jpeg, row, others in tqdm(frames, total=len(frame_times(people)), mininterval=10):
            writer.add(t, jpeg)
            rows.append(row)
            other_rows.extend(others)
    write_table(pd.DataFrame(rows), ctx.output.ball2d, truth.BALL2D, ctx.provenance())
    if room.balls:
        table = pd.DataFrame(other_rows, columns=list(truth.OTHER_BALLS2D.columns))
        write_table(table, ctx.output.other_balls, truth.OTHER_BALLS2D, ctx.provenance())
    logging.info("%s %s: %d frames, %d other balls' rows", p["session"], p["cam"], len(rows), len(other_rows))
