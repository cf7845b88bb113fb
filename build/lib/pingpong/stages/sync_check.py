"""Rule sync_check: a session's cameras agree on frame rate, count and times before triangulation
(pingpong.perception.sync); the per-camera table, or an error naming the cameras that disagree."""

from pingpong.common.artifacts import write_table
from pingpong.io.camera_streams import camera_frame_times
from pingpong.perception.schemas import SYNC
from pingpong.perception.sync import check_sync


def main(ctx):
    p = ctx.params
    streams = zip(p["cams"], ctx.input.streams, p["readings"], strict=True)
    times = {cam: camera_frame_times(path, p["strict"], **reading) for cam, path, reading in streams}
    write_table(check_sync(times, p["session"]), ctx.output.sync, SYNC, ctx.provenance())
