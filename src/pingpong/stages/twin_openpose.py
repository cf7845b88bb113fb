"""Rule twin_openpose: OpenPose's per-frame BODY_25 JSON as one camera would give it for a session, with a
detector's errors (`twin.openpose_sim`) and a spectator walking behind a court now and then (false people)."""

import numpy as np

from pingpong.common.artifacts import read_json, read_table
from pingpong.common.atomic import atomic_dir
from pingpong.common.camera import Camera
from pingpong.common.seeding import rng_for
from pingpong.io.openpose_json import format_keypoints_json, keypoints_filename
from pingpong.twin import truth
from pingpong.twin.openpose_sim import Carry, KeypointErrors, simulate_openpose_frames, spectator_joints

FRAME_CHUNK = 2000  # frames simulated at once: vectorised, in bounded memory


def main(ctx):
    p = ctx.params
    errors = KeypointErrors.from_config(p["keypoint_errors"])
    index = int(p["cam"].removeprefix("cam"))
    camera = Camera.from_dict(read_json(ctx.input.rig, truth.RIG)["cameras"][index])
    rng = rng_for(p["seed"], "twin_openpose", p["session"], p["cam"])
    people = read_table(ctx.input.people, truth.PEOPLE)
    bodies = np.stack([rows[list(truth.JOINT_COLUMNS)].to_numpy().reshape(-1, 25, 3)
                       for _, rows in people.groupby("person", sort=False)])
    # one spectator per session, the same person in every camera (seeded without the camera)
    spectator = spectator_joints(bodies.shape[1], errors.false_people_rate,
                                 rng_for(p["seed"], "twin_openpose_spectator", p["session"]))
    bodies = np.concatenate([bodies, spectator[None]])
    basename = f"{p['session']}_{p['cam']}"
    carry = Carry()
    with atomic_dir(ctx.output.folder) as folder:
        for first in range(0, bodies.shape[1], FRAME_CHUNK):
            chunk = bodies[:, first:first + FRAME_CHUNK]
            frames = simulate_openpose_frames(camera, chunk, rng, errors, carry)
            for frame, keypoints in enumerate(frames, start=first):
                (folder / keypoints_filename(basename, frame)).write_text(format_keypoints_json(keypoints))
