"""Rule twin_rig: the lab's true cameras and OptiTrack frame (ground truth, raw/twin_truth/rig.json)."""

from pingpong.common.artifacts import write_json
from pingpong.common.seeding import rng_for
from pingpong.twin import truth
from pingpong.twin.optitrack_sim import table_to_optitrack
from pingpong.twin.rig import make_rig


def main(ctx):
    p = ctx.params
    rng = rng_for(p["seed"], "twin_rig")
    cameras = make_rig(rng, p["n_cameras"], p["width"], p["height"])
    R, t = table_to_optitrack(rng)
    rig = {"cameras": [c.to_dict() for c in cameras],
           "optitrack_from_table": {"R": R.tolist(), "t": t.tolist()}}  # p_ot = R p_table + t
    write_json(rig, ctx.output.rig, truth.RIG, ctx.provenance())
