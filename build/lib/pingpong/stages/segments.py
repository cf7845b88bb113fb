"""Rule segments: one session's candidate hits (the paper's segments), kept or excluded with a reason."""

from pingpong.common.artifacts import read_table, write_table
from pingpong.curation.schemas import EVENTS, SEGMENTS
from pingpong.curation.segments import CurationRules, curate_segments, find_segments
from pingpong.perception.schemas import BALL3D, PADDLE, POSE3D


def main(ctx):
    p = ctx.params
    ball, pose = read_table(ctx.input.ball, BALL3D), read_table(ctx.input.pose, POSE3D)
    candidates = find_segments(ball, read_table(ctx.input.events, EVENTS), p["session"])
    curated = curate_segments(candidates, ball, pose, read_table(ctx.input.paddle, PADDLE),
                              CurationRules.from_config(p["rules"]))
    write_table(curated, ctx.output.segments, SEGMENTS, ctx.provenance())
