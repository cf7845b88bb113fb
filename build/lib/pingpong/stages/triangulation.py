"""Rule triangulation: the ball and both players' joints in 3D (table frame) on the camera clock."""

import logging

from pingpong.common.artifacts import read_table, write_table
from pingpong.perception.calibration import load_cameras
from pingpong.perception.schemas import BALL3D, DETECTIONS, POSE2D, POSE3D
from pingpong.perception.triangulation import ball3d_table, pose3d_table, reprojection_gate_px


def main(ctx):
    p = ctx.params
    all_cameras, _ = load_cameras(ctx.input.cameras)
    cameras = [next(c for c in all_cameras if c.name == name) for name in p["cams"]]
    prov = ctx.provenance()
    gate = reprojection_gate_px(cameras, p["max_reproj_share"])
    ball = ball3d_table(cameras, [read_table(f, DETECTIONS) for f in ctx.input.detections], gate,
                        p["min_views"])
    write_table(ball, ctx.output.ball3d, BALL3D, prov)
    pose = pose3d_table(cameras, [read_table(f, POSE2D) for f in ctx.input.pose2d], gate, p["min_views"])
    write_table(pose, ctx.output.pose3d, POSE3D, prov)
    logging.info("ball in 3D in %d of %d frames", ball["x"].notna().sum(), len(ball))
