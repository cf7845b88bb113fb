"""Rule pose2d: both players' 8 model joints in one camera's OpenPose output, assigned to their sides."""

from pingpong.common.artifacts import write_table
from pingpong.io.mcap_io import read_camera_times
from pingpong.perception.calibration import load_cameras
from pingpong.perception.pose2d import pose2d_table
from pingpong.perception.schemas import POSE2D


def main(ctx):
    p = ctx.params
    cameras, _ = load_cameras(ctx.input.cameras)
    camera = next(c for c in cameras if c.name == p["cam"])
    times = read_camera_times(ctx.input.mcap, strict=p["strict"])
    table = pose2d_table(ctx.input.openpose, camera, times, p["min_confidence"], p["model"], p["pattern"])
    write_table(table, ctx.output.pose2d, POSE2D, ctx.provenance())
