"""Rule sync_check: a session's cameras agree on frame rate, count and times before triangulation
(pingpong.perception.sync); the per-camera table, or an error naming the cameras that disagree."""

from pingpong.common.artifacts import write_table
from pingpong.io.mcap_io import read_camera_times
from pingpong.perception.schemas import SYNC
from pingpong.perception.sync import check_sync


def main(ctx):
    p = ctx.params
    streams = zip(p["cams"], ctx.input.streams, strict=True)
    times = {cam: read_camera_times(path, strict=p["strict"]) for cam, path in streams}
    write_table(check_sync(times, p["session"]), ctx.output.sync, SYNC, ctx.provenance())
