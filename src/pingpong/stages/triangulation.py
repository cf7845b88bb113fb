"""Rule triangulation: the ball and the scene's people's joints (every keypoint of the declared model) in 3D
(table frame) on the camera clock, and each camera's 2D ball after the views' agreement (the views the 3D ball
is triangulated from: triangulation.corrected_views)."""

import logging

import numpy as np
import pandas as pd

from pingpong.common.artifacts import read_table, write_table
from pingpong.common.atomic import atomic_dir
from pingpong.perception.ball_flight import FlightRule, ball_verdict, drop_phantoms
from pingpong.perception.calibration import load_cameras
from pingpong.perception.pose3d import pose3d_table
from pingpong.perception.scene import Scene
from pingpong.perception.schemas import BALL3D, BALL_CANDIDATES, DETECTIONS, POSE2D, POSE3D
from pingpong.perception.triangulation import (
    agreed_views,
    ball3d_frame,
    corrected_views,
    on_ball_tracks,
    reprojection_gate_px,
    views_table,
)


def main(ctx):
    p = ctx.params
    all_cameras, _ = load_cameras(ctx.input.cameras)
    cameras = [next(c for c in all_cameras if c.name == name) for name in p["cams"]]
    prov = ctx.provenance()
    detections = [read_table(f, DETECTIONS) for f in ctx.input.detections]
    candidates = [read_table(f, BALL_CANDIDATES) for f in ctx.input.candidates]
    ball, views = session_ball(cameras, detections, p, candidates)
    write_table(ball, ctx.output.ball3d, BALL3D, prov)
    with atomic_dir(ctx.output.ball_views) as folder:  # {cam}.parquet: the session's cameras vary (lab)
        for name, detected, found, uv in zip(p["cams"], detections, candidates, views.transpose(1, 0, 2),
                                             strict=True):
            write_table(views_table(detected, found, uv), folder / f"{name}.parquet", DETECTIONS, prov)
    pose, report = pose3d_table(cameras, [read_table(f, POSE2D) for f in ctx.input.pose2d],
                                Scene.from_config(p["scene"]), p["association_share"], p["max_reproj_share"],
                                p["pose_gate_noise_factor"], p["pose_confidence_weights"], p["min_views"],
                                p["pose_view_policy"], p["pose_max_mean_reproj_px"])
    write_table(pose, ctx.output.pose3d, POSE3D, prov)
    logging.info("joints' view policy %s (mean_error_under's threshold %.1f px)", p["pose_view_policy"],
                 p["pose_max_mean_reproj_px"])
    log_pose_report(report)


def session_ball(cameras: list, detections: list[pd.DataFrame], p: dict,
                 candidates: list[pd.DataFrame] | None = None) -> tuple[pd.DataFrame, np.ndarray]:
    """The session's 3D ball (BALL3D): points whose views agree (the reprojection gate; a camera's other
    candidates fill the views its detection leaves out where they agree: triangulation.rescue_views), kept
    only on a flight (pingpong.perception.ball_flight); and each camera's 2D ball after that agreement (N, C,
    2) px, NaN where none (triangulation.corrected_views): a point in flight is triangulated from exactly
    these views. Logs the phantoms dropped, whether the session has a ball, and what the agreement changed."""
    gate = reprojection_gate_px(cameras, p["max_reproj_share"])
    agreed = agreed_views(cameras, detections, gate, p["min_views"], candidates, p["ball_pair_min_frames"])
    ball = ball3d_frame(agreed)
    rule = FlightRule.from_config(p["ball_flight"])
    ball, counts = drop_phantoms(ball, rule)
    has_ball, verdict = ball_verdict(counts, len(ball))
    logging.log(logging.INFO if has_ball else logging.WARNING,
                "3D ball whose views agree in %d of %d frames; %s", int(agreed["n_views"].astype(bool).sum()),
                len(ball), verdict)
    views = corrected_views(agreed["detected"], agreed["pixels"], agreed["used_mask"],
                            *on_ball_tracks(agreed["times"], agreed["points"], rule))
    log_view_changes([c.name for c in cameras], agreed["detected"], views)
    return ball, views


def log_view_changes(names: list[str], detected: np.ndarray, views: np.ndarray) -> None:
    """Per camera, the detections the agreement kept and dropped and the views it added (candidates)."""
    had, has = np.isfinite(detected).all(axis=2), np.isfinite(views).all(axis=2)
    same = had & has & (detected == views).all(axis=2)
    for c, name in enumerate(names):
        logging.info("%s 2D ball after the views' agreement: %d detections kept, %d dropped, %d moved to "
                     "another candidate, %d added where it had none", name, same[:, c].sum(),
                     (had & ~has)[:, c].sum(), (had & has & ~same)[:, c].sum(), (~had & has)[:, c].sum())


def log_pose_report(report: dict) -> None:
    """The frames each camera gave each slot, as a table in the log, the gates and the DLT agreement."""
    lines = ["camera | " + " | ".join(f"{slot} kept / with joints" for slot in report["slots"])]
    for c, cam in enumerate(report["cameras"]):
        lines.append(f"{cam} | " + " | ".join(f"{report['frames_kept'][c, s]} / {report['frames_used'][c, s]}"
                                             for s in range(len(report["slots"]))))
    lines.append("found (>= 2 cameras) | " + " | ".join(str(n) for n in report["frames_found"]))
    logging.info("people per camera and slot, frames of %d:\n%s", report["frames"], "\n".join(lines))
    logging.info("joint gates %s px; %.1f %% of fitted joints dropped a view",
                 report["gate_px"].round(1).tolist(), 100 * report["views_dropped_share"])
    if report["dlt_agreement_mm"] is not None:
        logging.info("joints against a plain all-view DLT of the same views: median %.1f mm, p90 %.1f mm",
                     *report["dlt_agreement_mm"])
    if report["dlt_agreement_dropped_mm"] is not None:
        logging.info("  of those that dropped a view: median %.1f mm, p90 %.1f mm",
                     *report["dlt_agreement_dropped_mm"])
