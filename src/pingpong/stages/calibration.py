"""Rule calibration: every camera's intrinsics and table-frame extrinsics, and the OptiTrack-to-table fit."""

from pingpong.common.artifacts import write_json
from pingpong.io.calibration_import import read_anipose_toml, read_opencv_calibration
from pingpong.io.optitrack import read_optitrack_poses
from pingpong.perception.calibration import calibrate_camera, camera_folder_paths, optitrack_to_table
from pingpong.perception.schemas import CAMERAS


def main(ctx):
    p = ctx.params
    if p["import_path"]:  # an existing calibration, in the table frame
        reader = read_anipose_toml if str(p["import_path"]).endswith(".toml") else read_opencv_calibration
        cameras, reports = reader(p["import_path"], units=p["import_units"]), []
    else:
        pairs = [calibrate_camera(cam, *camera_folder_paths(folder))
                 for cam, folder in zip(p["cameras"], p["folders"], strict=True)]
        cameras, reports = [c for c, _ in pairs], [r for _, r in pairs]
    T, rms = optitrack_to_table(read_optitrack_poses(ctx.input.optitrack, p["strict"], p["take_start_ns"]))
    write_json({"cameras": [c.to_dict() for c in cameras], "reports": reports,
                "T_table_from_optitrack": T.tolist(), "optitrack_fit_rms_m": rms},
               ctx.output.cameras, CAMERAS, ctx.provenance())
