"""Rule pose_trc: one slot's (player's or subject's) joints of a session as a TRC marker file for OpenSim
and Pose2Sim (pingpong.io.trc): every triangulated keypoint a marker named by its joint, in metres, in
OpenSim's y-up axes, on the camera clock; unfiltered, as triangulated."""

import logging

import numpy as np

from pingpong.common.artifacts import read_table
from pingpong.io.trc import opensim_axes, write_trc
from pingpong.perception.schemas import POSE3D, table_joints


def main(ctx):
    pose = read_table(ctx.input.pose3d, POSE3D)
    rows = pose[pose["player"] == ctx.params["slot"]].sort_values("time_ns")
    joints = table_joints(rows.columns, "x")
    points = np.stack([rows[[f"{j}_{a}" for a in "xyz"]].to_numpy(float) for j in joints], axis=1)
    time_ns = rows["time_ns"].to_numpy(np.int64)
    write_trc(ctx.output.trc, (time_ns - time_ns[0]) * 1e-9, list(joints), opensim_axes(points))
    logging.info("%s: %d frames, %d markers, %.1f %% of the values present", ctx.params["slot"], len(rows),
                 len(joints), 100 * np.isfinite(points).mean())
