"""Rule pose2d: both players' 8 model joints in one camera's OpenPose output, assigned to their sides."""

from pingpong.common.artifacts import write_table
from pingpong.io.camera_streams import camera_frame_times
from pingpong.perception.calibration import load_cameras
from pingpong.perception.pose2d import pose2d_table
from pingpong.perception.schemas import POSE2D


def main(ctx):
    p = ctx.params
    cameras, _ = load_cameras(ctx.input.cameras)
    camera = next(c for c in cameras if c.name == p["cam"])
    times = camera_frame_times(ctx.input.stream, p["strict"], **p["reading"])
    table = pose2d_table(ctx.input.openpose, camera, times, p["min_confidence"], p["model"], p["pattern"])
    write_table(table, ctx.output.pose2d, POSE2D, ctx.provenance())
