"""The scene's people in 3D from every camera's 2D people: matched across views by geometry on the 8 model
joints (`association`), then every keypoint of the declared model by the subset search of
`triangulate_robust` under a view policy (VIEW_POLICIES): each view within a gate scaled by the image size
and the keypoints' noise (`pose_gate_px`), or Pose2Sim's mean reprojection error under a threshold."""

import numpy as np
import pandas as pd

from pingpong.common.camera import Camera
from pingpong.frames import MODEL_JOINTS
from pingpong.perception.association import associate, people_arrays
from pingpong.perception.scene import Scene
from pingpong.perception.schemas import POSE3D_VALUES, table_joints
from pingpong.perception.triangulation import (
    _aligned_times,
    pose_gate_px,
    reprojection_errors,
    reprojection_gate_px,
    triangulate_robust,
)

# config perception.pose_view_policy: which views of a joint its fit keeps
VIEW_POLICIES = ("all_within_gate", "mean_error_under")


class PoseSceneError(ValueError):
    """No joint of anyone in 3D: says what was seen and what the scene asked for."""


def chosen_joints(people: list[tuple], choice: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (F, S, J, C, 2) and confidences (F, S, J, C) of the people chosen per slot (choice (F, S, C)),
    NaN and 0 where a camera gives a slot nobody."""
    px, conf = [], []
    frames = np.arange(len(choice))[:, None]
    for c, (p, w, _) in enumerate(people):  # index -1 picks an appended empty person
        pick = choice[..., c]
        px.append(np.concatenate([p, np.full((len(p), 1, *p.shape[2:]), np.nan)], axis=1)[frames, pick])
        conf.append(np.concatenate([w, np.zeros((len(w), 1, w.shape[2]))], axis=1)[frames, pick])
    return np.stack(px, axis=3), np.stack(conf, axis=3)


def pose3d_table(cameras: list[Camera], poses2d: list[pd.DataFrame], scene: Scene, association_share: float,
                 gate_share: float, noise_factor: float, weighted: bool, min_views: int = 2,
                 view_policy: str = "all_within_gate", max_mean_px: float = 15.0
                 ) -> tuple[pd.DataFrame, dict]:
    """The scene's slots' joints in 3D per frame (rows: slot-major, then frame), and a report.

    poses2d: each camera's POSE2D table (every person per frame; its joints are the declared model's
    keypoints). People are matched on the 8 model joints; the association gate per camera is
    association_share of its image diagonal. Each joint is fitted by triangulate_robust (weighted by
    OpenPose's confidence if `weighted`) under view_policy: 'all_within_gate' with the gate
    pose_gate_px(gate_share, noise_factor), which the noise of the model joints' all-view fit widens (so
    the model joints do not move with the model's other keypoints); 'mean_error_under' (Pose2Sim's) with
    the views' mean reprojection error within max_mean_px (px). A joint seen well by < min_views cameras
    is NaN. Columns: time_ns, player (the slot) and per joint {name}_x, _y, _z (m, the cameras' world),
    _views (the views used, 0 where unfitted) and _reproj_px (their RMS reprojection error, px).
    Raises PoseSceneError when no joint is found.
    The report: per camera and slot the frames it gave the slot a person (`frames_kept`, (C, S)) and the
    frames it gave at least one joint (`frames_used`), the gates, and the agreement of the joints with a
    plain all-view DLT of the same people's views (`dlt_agreement_mm`: median, p90; over the joints that
    dropped a view, where the two can differ at all: `dlt_agreement_dropped_mm`)."""
    if view_policy not in VIEW_POLICIES:
        raise ValueError(f"view policy must be one of {VIEW_POLICIES}, got {view_policy!r}")
    times = _aligned_times(poses2d)
    joints = table_joints(poses2d[0].columns, "u")
    model = [joints.index(name) for name in MODEL_JOINTS]
    people = [people_arrays(t, times, joints) for t in poses2d]
    choice = associate(cameras, [(p[:, :, model], w[:, :, model], ids) for p, w, ids in people], scene,
                       reprojection_gate_px(cameras, association_share))
    px, conf = chosen_joints(people, choice)  # (F, S, J, C, ...)
    n_frames, n_slots, n_joints = px.shape[:3]
    flat_px = px.reshape(-1, len(cameras), 2)
    flat_conf = conf.reshape(-1, len(cameras)) if weighted else None
    plain = triangulate_robust(cameras, flat_px, np.inf)  # every view, unweighted: the agreement's reference
    if view_policy == "all_within_gate":
        model_rows = np.isin(np.arange(len(flat_px)) % n_joints, model)
        gate = _joint_gate(cameras, flat_px[model_rows], None if flat_conf is None else flat_conf[model_rows],
                           plain, model_rows, gate_share, noise_factor, min_views)
        tri = triangulate_robust(cameras, flat_px, gate, min_views, flat_conf)
    else:
        gate = np.full(len(cameras), np.inf)
        tri = triangulate_robust(cameras, flat_px, gate, min_views, flat_conf, max_mean_px)
    report = _report(cameras, scene, choice, tri, plain["points"], gate, plain["n_views"])
    if not np.isfinite(tri["points"]).any():
        raise PoseSceneError(_why_empty(cameras, people, scene, choice, association_share))
    values = dict(zip(POSE3D_VALUES, (*tri["points"].T, tri["n_views"], tri["reproj_rms_px"]), strict=True))
    values = {q: v.reshape(n_frames, n_slots, n_joints) for q, v in values.items()}
    parts = []
    for s, slot in enumerate(scene.slots):
        cols = {f"{name}_{q}": v[:, s, k] for k, name in enumerate(joints) for q, v in values.items()}
        parts.append(pd.DataFrame({"time_ns": times, "player": slot, **cols}))
    return pd.concat(parts, ignore_index=True), report


def _joint_gate(cameras: list[Camera], px: np.ndarray, conf: np.ndarray | None, plain: dict, rows: np.ndarray,
                gate_share: float, noise_factor: float, min_views: int) -> np.ndarray:
    """pose_gate_px from the all-view fit of the model joints' views px (N, C, 2) (rows: which of plain's
    points they are; plain serves where the fit is plain's: unweighted, min_views 2)."""
    if conf is None and min_views == 2:
        everything = {k: v[rows] for k, v in plain.items()}
    else:
        everything = triangulate_robust(cameras, px, np.inf, min_views, conf)
    errors = reprojection_errors(cameras, everything["points"], px)
    return pose_gate_px(cameras, errors, everything["used_mask"], gate_share, noise_factor)


def _report(cameras: list[Camera], scene: Scene, choice: np.ndarray, tri: dict, plain: np.ndarray,
            gate: np.ndarray, seen_views: np.ndarray) -> dict:
    """What pose3d_table's docstring lists, from the association's choice, the joints' fit and the plain
    all-view DLT of the same views (plain (N, 3); seen_views (N,): how many views each joint had)."""
    n_frames, n_slots, n_cams = choice.shape
    used = tri["used_mask"].reshape(n_frames, n_slots, -1, n_cams).any(axis=2)  # (F, S, C)
    gap = 1e3 * np.linalg.norm(tri["points"] - plain, axis=1)
    dropped = tri["n_views"] < seen_views
    fitted = np.isfinite(tri["points"]).all(axis=1)
    gap_dropped = gap[np.isfinite(gap) & dropped]  # where the two differ at all
    gap = gap[np.isfinite(gap)]
    return {"slots": list(scene.slots), "cameras": [c.name for c in cameras], "frames": n_frames,
            "frames_kept": (choice >= 0).sum(axis=0).T, "frames_used": used.sum(axis=0).T,
            "frames_found": ((choice >= 0).sum(axis=2) >= 2).sum(axis=0), "gate_px": gate,
            "dlt_agreement_mm": _median_p90(gap), "dlt_agreement_dropped_mm": _median_p90(gap_dropped),
            "views_dropped_share": float(dropped[fitted].mean()) if fitted.any() else 0.0}


def _median_p90(values: np.ndarray) -> tuple[float, float] | None:
    return (float(np.median(values)), float(np.percentile(values, 90))) if len(values) else None


def _why_empty(cameras: list[Camera], people: list[tuple], scene: Scene, choice: np.ndarray,
               association_share: float) -> str:
    """Why no joint was found: who the cameras saw and what the scene asked for."""
    seen = ", ".join(f"{cam.name} {int((p[2] >= 0).any(axis=1).sum())}" for cam, p in zip(cameras, people,
                                                                                           strict=True))
    text = (f"no joint of anyone in 3D in {len(choice)} frames; frames with people per camera: {seen}; "
            f"frames a slot was matched across >= 2 cameras: {int(((choice >= 0).sum(axis=2) >= 2).sum())}. ")
    if scene.mode == "players":
        text += (f"The scene is 'players': a person counts only within {scene.area_margin_m} m of a player's "
                 f"area (|x| <= {scene.area_half_width_m} m, |y| in {list(scene.area_y_m)} m of the table "
                 "frame). Is the calibration's world the table frame? A pose-only lab sets "
                 "perception.scene.mode: subjects. ")
    return text + (f"People agree across views within the association gate of {association_share} of each "
                   "image diagonal (perception.association_share); check the calibration and that each "
                   "camera's OpenPose folder is its own.")
