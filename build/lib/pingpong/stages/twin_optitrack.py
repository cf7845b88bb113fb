"""Rule twin_optitrack: the session's OptiTrack stream (paddles, table markers) in Motive's own frame."""

import numpy as np

from pingpong.common.artifacts import read_json, read_table
from pingpong.common.seeding import rng_for
from pingpong.twin import truth
from pingpong.twin.optitrack_sim import write_optitrack_session


def main(ctx):
    p = ctx.params
    rig = read_json(ctx.input.rig, truth.RIG)["optitrack_from_table"]
    paddles = read_table(ctx.input.paddles, truth.PADDLES)
    poses, times = {}, None
    for player, rows in paddles.groupby("player", sort=False):
        times = rows["time_ns"].to_numpy()
        poses[player] = (rows[["px", "py", "pz"]].to_numpy(),
                         rows[list(truth.ROT_COLUMNS)].to_numpy().reshape(-1, 3, 3))
    write_optitrack_session(ctx.output.mcap, times, poses, (np.array(rig["R"]), np.array(rig["t"])),
                            rng_for(p["seed"], "twin_optitrack", p["session"]))
