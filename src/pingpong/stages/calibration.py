"""Rule calibration: every camera's intrinsics and extrinsics, fitted on the lab's board views and placed
by the table mat, a board at a known pose or listed scene points, or imported; checked by reprojection;
moved to the recordings' window where they record one of the calibrated image (perception.frame_crop); and
the OptiTrack-to-table fit where the lab has OptiTrack."""

from pingpong.common.artifacts import write_json
from pingpong.io.optitrack import read_optitrack_poses
from pingpong.perception.calibration import (
    crop_to_recorded,
    extrinsics_method,
    fit_calibration,
    import_calibration,
    intrinsics_setup,
    optitrack_record,
)
from pingpong.perception.schemas import CAMERAS


def main(ctx):
    p = ctx.params
    import_path = ctx.optional_input("calibration_import")
    if import_path:
        shots = list(ctx.input.get("shots") or [])  # every camera's table shot (p["cameras"] order), or none
        cameras, checks = import_calibration(import_path, p["import_units"], p["import_world"], p["cameras"],
                                             dict(zip(p["cameras"], shots, strict=bool(shots))),
                                             p["max_rms_share"], p["import_names"])
        frame = "lab" if p["import_world"] == "lab" else "table"
        record = {"reports": [], "import_checks": checks}
    else:
        setup = intrinsics_setup(p["board"], p["fit_k3"], p["source"])
        method = extrinsics_method(p["extrinsics"], p["board"], ctx.optional_input("scene_points"))
        cameras, reports = fit_calibration(p["cameras"], p["folders"], setup, p["max_rms_share"], method)
        record, frame = {"reports": reports}, method.frame
    cameras = crop_to_recorded(cameras, p["frame_crop"])  # after the checks: captures are calibrated-size
    optitrack = ctx.optional_input("optitrack")  # none: a lab without OptiTrack
    poses = None if optitrack is None else read_optitrack_poses(optitrack, p["strict"], p["take_start_ns"])
    write_json({"cameras": [c.to_dict() for c in cameras], **record, "world_frame": frame,
                **optitrack_record(poses)}, ctx.output.cameras, CAMERAS, ctx.provenance())
