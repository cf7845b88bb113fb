"""Rule paddle: both paddles' poses in the table frame on the camera clock, gaps marked."""


from pingpong.common.artifacts import write_table
from pingpong.io.camera_streams import camera_frame_times
from pingpong.io.optitrack import read_optitrack_poses
from pingpong.perception.calibration import load_cameras, table_from_optitrack
from pingpong.perception.paddle import paddle_table
from pingpong.perception.schemas import PADDLE


def main(ctx):
    p = ctx.params
    _, calibration = load_cameras(ctx.input.cameras)
    frame_times = camera_frame_times(ctx.input.clock, p["strict"], **p["reading"])
    poses = read_optitrack_poses(ctx.input.optitrack, p["strict"], p["take_start_ns"])
    T = table_from_optitrack(calibration, ctx.input.cameras)
    table = paddle_table(poses, p["bodies"], T, frame_times, p["max_gap_s"])
    write_table(table, ctx.output.paddle, PADDLE, ctx.provenance())
