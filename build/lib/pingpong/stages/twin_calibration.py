"""Rule twin_calibration: the calibration captures of every camera (checkerboard views, table mat)."""

from pingpong.common.artifacts import read_json
from pingpong.common.camera import Camera
from pingpong.common.seeding import rng_for
from pingpong.twin import truth
from pingpong.twin.calibration_images import write_calibration_images
from pingpong.twin.render import make_lab


def main(ctx):
    p = ctx.params
    cameras = [Camera.from_dict(c) for c in read_json(ctx.input.rig, truth.RIG)["cameras"]]
    write_calibration_images(str(p["folder"]), cameras, make_lab(rng_for(p["seed"], "twin_lab")),
                             rng_for(p["seed"], "twin_calibration"), p["views"])
