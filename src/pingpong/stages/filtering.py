"""Rule filtering: ball events found on the raw 3D ball, then ball (between events) and pose low-passed."""

from pingpong.common.artifacts import read_table, write_table
from pingpong.curation.filtering import filter_session
from pingpong.curation.schemas import EVENTS
from pingpong.perception.schemas import BALL3D, PADDLE, POSE3D


def main(ctx):
    p = ctx.params
    i = ctx.input
    ball, pose, events = filter_session(read_table(i.ball3d, BALL3D), read_table(i.pose3d, POSE3D),
                                        read_table(i.paddle, PADDLE), p["cutoff_ball_hz"],
                                        p["cutoff_pose_hz"])
    prov = ctx.provenance()
    write_table(ball, ctx.output.ball, BALL3D, prov)
    write_table(pose, ctx.output.pose, POSE3D, prov)
    write_table(events, ctx.output.events, EVENTS, prov)
