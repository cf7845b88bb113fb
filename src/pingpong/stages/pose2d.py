"""Rule pose2d: every person's 8 model joints in one camera's OpenPose output, followed over time (who is
who is matched across cameras by the triangulation rule)."""

import logging

from pingpong.common.artifacts import write_table
from pingpong.io.camera_streams import CameraStreamError, camera_frame_size, camera_frame_times
from pingpong.perception.calibration import load_cameras
from pingpong.perception.pose2d import pose2d_table
from pingpong.perception.schemas import POSE2D


def main(ctx):
    p = ctx.params
    cameras, _ = load_cameras(ctx.input.cameras)
    camera = next((c for c in cameras if c.name == p["cam"]), None)
    if camera is None:
        raise ValueError(f"{ctx.input.cameras}: no camera {p['cam']!r} (cameras: "
                         f"{', '.join(c.name for c in cameras)}); expected one calibrated for each stream")
    times = camera_frame_times(ctx.input.stream, p["strict"], **p["reading"])
    width, height = camera_frame_size(ctx.input.stream, p["strict"], **p["reading"])
    if (width, height) != (camera.width, camera.height):  # pixels would land off their calibrated rays
        raise CameraStreamError(f"{ctx.input.stream}: frames of {width} x {height} px, but camera "
                                f"{camera.name} is calibrated for {camera.width} x {camera.height} px in "
                                f"{ctx.input.cameras}; expected the stream at the calibration's size (not "
                                "cropped or scaled)")
    table = pose2d_table(ctx.input.openpose, times, p["min_confidence"], p["model"], p["pattern"])
    people = table.loc[table["person"] >= 0]
    logging.info("%s: people in %d of %d frames, %d tracklets", p["cam"], people["time_ns"].nunique(),
                 len(times), people["person"].nunique())
    write_table(table, ctx.output.pose2d, POSE2D, ctx.provenance())
