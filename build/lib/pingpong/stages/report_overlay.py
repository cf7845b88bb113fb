"""Rule report_overlay: the 3D ball and joints reprojected onto a few frames of one camera
(pingpong.reports.overlays), reports/figures/overlay_{session}_{cam}.png."""

import cv2

from pingpong.common.artifacts import read_table
from pingpong.common.atomic import write_bytes_atomic
from pingpong.io.camera_streams import open_camera_stream
from pingpong.perception.calibration import load_cameras
from pingpong.perception.schemas import BALL3D, DETECTIONS, POSE3D
from pingpong.reports.overlays import session_overlay


def main(ctx):
    p, i = ctx.params, ctx.input
    camera = next(c for c in load_cameras(i.cameras)[0] if c.name == p["cam"])
    _, frames = open_camera_stream(i.stream, p["strict"], **p["reading"])
    grid = session_overlay(frames, camera, read_table(i.ball3d, BALL3D), read_table(i.pose3d, POSE3D),
                           read_table(i.detections, DETECTIONS), p["n_frames"], f"{p['session']} {p['cam']}")
    write_bytes_atomic(ctx.output.figure, cv2.imencode(".png", grid)[1].tobytes())
