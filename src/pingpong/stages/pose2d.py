"""Rule pose2d: every person's keypoints in one camera's OpenPose output, followed over time (who is
who is matched across cameras by the triangulation rule)."""

import logging

from pingpong.common.artifacts import write_table
from pingpong.io.camera_streams import camera_frame_times, check_calibrated_size
from pingpong.perception.calibration import calibrated_camera
from pingpong.perception.pose2d import pose2d_table
from pingpong.perception.schemas import POSE2D


def main(ctx):
    p = ctx.params
    camera = calibrated_camera(ctx.input.cameras, p["cam"])
    times = camera_frame_times(ctx.input.stream, p["strict"], **p["reading"])
    check_calibrated_size(ctx.input.stream, camera, ctx.input.cameras, p["strict"], **p["reading"])
    table = pose2d_table(ctx.input.openpose, times, p["min_confidence"], p["model"], p["pattern"])
    people = table.loc[table["person"] >= 0]
    logging.info("%s: people in %d of %d frames, %d tracklets", p["cam"], people["time_ns"].nunique(),
                 len(times), people["person"].nunique())
    write_table(table, ctx.output.pose2d, POSE2D, ctx.provenance())
