"""Rule filtering: ball events found on the raw 3D ball, then ball (between events) and pose low-passed
zero-phase; beside them the causal inputs' measurements, cleaned with past-only checks and not filtered
(the dataset low-passes them forwards, per input channel: curation.dataset)."""

from pingpong.common.artifacts import read_table, write_table
from pingpong.curation.causal import causal_session_inputs
from pingpong.curation.filtering import filter_session
from pingpong.curation.schemas import EVENTS
from pingpong.perception.schemas import BALL3D, PADDLE, POSE3D


def main(ctx):
    p = ctx.params
    i = ctx.input
    ball3d = read_table(i.ball3d, BALL3D)
    # the model joints alone: curation cleans and low-passes those, its tables carry no other keypoint
    pose3d = read_table(i.pose3d, POSE3D, columns=list(POSE3D.columns))
    ball, pose, events = filter_session(ball3d, pose3d, read_table(i.paddle, PADDLE), p["cutoff_ball_hz"],
                                        p["cutoff_pose_hz"])
    causal_ball, causal_pose = causal_session_inputs(ball3d, pose3d, cutoff_ball_hz=None, cutoff_pose_hz=None)
    prov = ctx.provenance()
    write_table(ball, ctx.output.ball, BALL3D, prov)
    write_table(pose, ctx.output.pose, POSE3D, prov)
    write_table(events, ctx.output.events, EVENTS, prov)
    write_table(causal_ball, ctx.output.causal_ball, BALL3D, prov)
    write_table(causal_pose, ctx.output.causal_pose, POSE3D, prov)
