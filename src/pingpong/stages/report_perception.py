"""Rule report_perception: perception against the twin's truth (twin runs only)."""

from pathlib import Path

import pandas as pd

from pingpong.common.artifacts import read_json, read_table
from pingpong.common.camera import Camera
from pingpong.frames import MODEL_JOINT_IDS
from pingpong.perception.calibration import load_cameras
from pingpong.perception.schemas import BALL3D, DETECTIONS, PADDLE, POSE3D
from pingpong.reports import perception_accuracy as acc
from pingpong.reports.tables import write_report_table
from pingpong.twin import truth
from pingpong.twin.session import ball_positions_at

CAPTION = """Each perception stage measured against the digital twin's ground truth over every session
of this run, beside the threshold the perception tests hold it to (`ok`). Calibration: the worse of
the intrinsic and extrinsic reprojection RMS, and the calibrated camera centre against the true one.
Detection: each camera's own ball detector alone (rows "{session} {cam} one-view ..."): recall on frames
where at least half of the ball shows, median centre error on those, and detections with no ball
within 5 px. Multi-view (rows "{session} {cam} multi-view ..."): the same figures, with the same
thresholds, of each camera's 2D ball after the cameras' agreement (interim/ball_views/: its detection
kept where it agrees with the 3D ball of the other views, dropped where they agree elsewhere, and a
candidate of its detector taken where it agrees with them; the views the 3D ball is triangulated
from). 3D: triangulated ball and the 8 model joints against truth
(medians over all frames where both exist). Paddles: resampled OptiTrack poses against truth."""


def main(ctx):
    p, i = ctx.params, ctx.input
    cameras, calibration = load_cameras(i.cameras)
    rig = [Camera.from_dict(c) for c in read_json(i.rig, truth.RIG)["cameras"]]
    rows = acc.calibration_rows(cameras, calibration["reports"], rig)
    n_cams = len(p["cams"])
    for k, session in enumerate(p["sessions"]):
        for c, cam in enumerate(p["cams"]):
            j = k * n_cams + c  # detections and pixel truth are listed session by session
            truth2d = read_table(i.ball2d[j], truth.BALL2D)
            rows += acc.detection_rows(f"{session} {cam} one-view", read_table(i.detections[j], DETECTIONS),
                                       truth2d)
            views = read_table(Path(i.ball_views[k]) / f"{cam}.parquet", DETECTIONS)
            rows += acc.detection_rows(f"{session} {cam} multi-view", views, truth2d)
        ball3d = read_table(i.ball3d[k], BALL3D)
        true_ball = ball_positions_at(read_table(i.ball[k], truth.BALL), ball3d["time_ns"].to_numpy())
        rows += acc.ball3d_rows(ball3d, true_ball)
        rows += acc.pose3d_rows(read_table(i.pose3d[k], POSE3D), read_table(i.people[k], truth.PEOPLE),
                                MODEL_JOINT_IDS)
        rows += acc.paddle_rows(read_table(i.paddle[k], PADDLE), read_table(i.paddles[k], truth.PADDLES))
    write_report_table(pd.DataFrame(rows), ctx.output.md, ctx.output.csv, "Perception accuracy", CAPTION)
