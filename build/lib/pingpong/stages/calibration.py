"""Rule calibration: every camera's intrinsics and table-frame extrinsics, fitted on the lab's board or
imported, checked by reprojection; and the OptiTrack-to-table fit where the lab has OptiTrack."""

from pingpong.common.artifacts import write_json
from pingpong.io.optitrack import read_optitrack_poses
from pingpong.perception.calibration import (
    fit_calibration,
    import_calibration,
    intrinsics_setup,
    optitrack_record,
)
from pingpong.perception.schemas import CAMERAS


def main(ctx):
    p = ctx.params
    shots = list(ctx.input.get("captures") or [])  # every camera's table.png (p["cameras"] order), or none
    if p["import_path"]:
        cameras, checks = import_calibration(p["import_path"], p["import_units"], p["import_world"],
                                             p["cameras"], dict(zip(p["cameras"], shots, strict=bool(shots))),
                                             p["max_rms_share"])
        record = {"reports": [], "import_checks": checks}
    else:
        setup = intrinsics_setup(p["board"], p["fit_k3"], p["source"])
        cameras, reports = fit_calibration(p["cameras"], p["folders"], setup, p["max_rms_share"])
        record = {"reports": reports}
    optitrack = ctx.input.get("optitrack") or None  # a list of one, or none: a lab without OptiTrack
    optitrack = optitrack if optitrack is None or isinstance(optitrack, str) else optitrack[0]
    poses = None if optitrack is None else read_optitrack_poses(optitrack, p["strict"], p["take_start_ns"])
    write_json({"cameras": [c.to_dict() for c in cameras], **record, **optitrack_record(poses)},
               ctx.output.cameras, CAMERAS, ctx.provenance())
