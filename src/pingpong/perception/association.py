"""People matched across cameras by geometry (cf. Pose2Sim's person association).

Per frame and slot of the scene (a player, or a subject), one person or none is chosen in each camera:
among every combination of the cameras' people (at least two cameras), those whose views triangulate
consistently (each view's median joint reprojection error within its camera's association gate, over
at least MIN_JOINTS joints) compete; the most views win, then (players) one inside the player's area
over one only within its margin, then the smallest error. So a bystander seen by one camera only never
agrees with the other views and is never used, and a person's split tracklet (one extra detection)
costs no frame. Players must stand near their area (the median of the fitted joints, table frame);
subjects may be anywhere and keep their labels from frame to frame by continuity of their 3D position.

Continuity (`foreign_tracklets`): geometry alone cannot tell a slot's person from someone who
stands near its area, or who overlaps it in one camera while another camera misses it, in the frames
where that someone's views agree as well as the person's. But a camera's tracklet that was seen beside
the slot's chosen person of that camera (same frame, another tracklet) in more frames than it was
chosen for the slot is someone else; a second pass chooses again without such tracklets. A gate on the
slot's recent 3D position would need a speed bound and a memory: a player unseen for 0.3 s may move
as far as a bystander at the table's corner stands from him, and a gate that once follows the wrong
person keeps following him. The tracklets carry who is who across such gaps already.
"""

import warnings
from itertools import product

import numpy as np
import pandas as pd
from scipy.optimize import linear_sum_assignment

from pingpong.common.camera import Camera
from pingpong.frames import MODEL_JOINTS
from pingpong.perception.pose2d import nanmedian_last
from pingpong.perception.scene import Scene
from pingpong.perception.triangulation import reprojection_errors, triangulate_dlt

MIN_JOINTS = 3  # joints a view must share with the fit for its agreement to count
# A view's gate grows to this share of its person's torso in the image: a detector errs in proportion to
# the person's size (COCO's per-keypoint sigmas are shares of it; twin.keypoint_errors), so a near,
# large person's views disagree by more pixels than a far one's. About 2.5x a shoulder's or hip's RMS
# error at COCO's sigmas (torso ~0.65 s: 0.3 torso ~ 0.2 s against sigma 0.08-0.11 s).
TORSO_GATE_SHARE = 0.3
TORSO_JOINTS = ((0, 6), (3, 7))  # model joints (MODEL_JOINT_IDS order): each shoulder and its hip
NEW_LABEL_M = 1e3  # cost of starting a subject label afresh rather than continuing one (m)


def people_arrays(table: pd.DataFrame, times: np.ndarray, joints=MODEL_JOINTS
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One camera's POSE2D table as arrays on the clock times (F,): pixels (F, P, J, 2) (NaN gaps) and
    confidences (F, P, J) of the joints (names; the 8 model joints by default), and person ids (F, P)
    (-1 where a frame has fewer people)."""
    rows = table[table["person"] >= 0]
    frame = np.searchsorted(times, rows["time_ns"].to_numpy())
    slot = rows.groupby("time_ns").cumcount().to_numpy()
    n_people = slot.max() + 1 if len(slot) else 0
    px = np.full((len(times), n_people, len(joints), 2), np.nan)
    conf = np.zeros((len(times), n_people, len(joints)))
    person = np.full((len(times), n_people), -1)
    px[frame, slot] = np.stack([rows[[f"{j}_u", f"{j}_v"]].to_numpy() for j in joints], 1)
    conf[frame, slot] = rows[[f"{j}_conf" for j in joints]].to_numpy()
    person[frame, slot] = rows["person"].to_numpy()
    return px, conf, person


def torso_lengths(px: np.ndarray) -> np.ndarray:
    """(...) a person's torso in the image (px): the mean of its shoulder-to-hip distances seen, from model
    joints (..., J, 2); NaN where neither is."""
    lengths = np.stack([np.linalg.norm(px[..., a, :] - px[..., b, :], axis=-1) for a, b in TORSO_JOINTS], -1)
    return np.nanmean(lengths, axis=-1)


def _median_error(errors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per point and view, the median over joints (axis 1) of finite errors (inf where none), and how many
    there were."""
    count = np.isfinite(errors).sum(axis=1)
    return np.where(count > 0, nanmedian_last(np.moveaxis(errors, 1, -1)), np.inf), count


def combination_fits(cameras: list[Camera], px: list[np.ndarray], conf: list[np.ndarray],
                     gate_px: np.ndarray) -> tuple[list[tuple], np.ndarray, np.ndarray, np.ndarray]:
    """Every combination of one person or none per camera (>= 2 cameras) fitted in every frame.

    px[c] (F, P_c, J, 2), conf[c] (F, P_c, J): camera c's people (people_arrays). Returns the
    combinations (tuples of a person index or -1 per camera), and per combination and frame whether
    its views agree (K, F), its mean error over gate (K, F; inf where they do not agree) and the median
    of its fitted joints (K, F, 3). A view's gate is its camera's gate_px, or TORSO_GATE_SHARE of its
    person's torso in the image where that is more."""
    n_frames = len(px[0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN: a person without a torso pair
        torso = [torso_lengths(p) for p in px]  # (F, P_c) per camera
    P = np.stack([cam.P for cam in cameras])
    undistorted = [cam.undistort_pixels(p.reshape(-1, 2)).reshape(p.shape) for cam, p in zip(cameras, px,
                                                                                            strict=True)]
    combos = [k for k in product(*[range(-1, p.shape[1]) for p in px]) if sum(i >= 0 for i in k) >= 2]
    agree = np.zeros((len(combos), n_frames), bool)
    error = np.full((len(combos), n_frames), np.inf)
    centre = np.full((len(combos), n_frames, 3), np.nan)
    for k, combo in enumerate(combos):
        views = [c for c, i in enumerate(combo) if i >= 0]
        present = np.all([np.isfinite(px[c][:, combo[c]]).any(axis=(-1, -2)) for c in views], axis=0)
        frames = np.flatnonzero(present)
        if len(frames) == 0:
            continue
        sub = np.stack([px[c][frames, combo[c]] for c in views], axis=2)  # (n, J, V, 2)
        und = np.stack([undistorted[c][frames, combo[c]] for c in views], axis=2)
        weight = np.stack([conf[c][frames, combo[c]] for c in views], axis=2)
        n, n_joints, n_views = sub.shape[:3]
        points = triangulate_dlt(P[views], und.reshape(-1, n_views, 2), np.isfinite(und).all(-1).reshape(
            -1, n_views), weight.reshape(-1, n_views))
        errors = reprojection_errors([cameras[c] for c in views], points, sub.reshape(-1, n_views, 2))
        median, count = _median_error(errors.reshape(n, n_joints, n_views))
        gate = [np.fmax(gate_px[c], TORSO_GATE_SHARE * torso[c][frames, combo[c]]) for c in views]
        ratio = median / np.stack(gate, axis=1)
        ok = ((ratio <= 1) & (count >= MIN_JOINTS)).all(axis=1)
        agree[k, frames] = ok
        error[k, frames[ok]] = ratio[ok].mean(axis=1)
        with warnings.catch_warnings():  # all-NaN: a frame whose views fit no joint
            warnings.simplefilter("ignore", RuntimeWarning)
            centre[k, frames] = np.nanmedian(points.reshape(n, n_joints, 3), axis=1)
    return combos, agree, error, centre


def associate(cameras: list[Camera], people: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
              scene: Scene, gate_px: np.ndarray) -> np.ndarray:
    """(F, S, C) the person index (into people_arrays' P axis) each camera gives each slot of the scene
    per frame, -1 where none; a slot is filled by at least two cameras or by none.

    people: people_arrays of each camera; gate_px (C,): the association gate per camera, px."""
    fits = combination_fits(cameras, [p[0] for p in people], [p[1] for p in people], gate_px)
    ids = [p[2] for p in people]
    choice = _choose(fits, ids, scene, None)
    foreign = foreign_tracklets(choice, ids, pooled=scene.mode == "subjects")
    if any(f.any() for f in foreign):
        choice = _choose(fits, ids, scene, foreign)
    return choice


def _choose(fits: tuple, ids: list[np.ndarray], scene: Scene, foreign: list[np.ndarray] | None) -> np.ndarray:
    """associate's choice from combination_fits' output, slot by slot, each camera's person used once per
    frame; a view of a tracklet foreign to the slot (foreign_tracklets; in subjects mode, foreign to every
    slot, since labels are set afterwards) is not used."""
    combos, agree, error, centre = fits
    n_frames, n_cams = len(ids[0]), len(ids)
    taken = [np.zeros((n_frames, max(i.shape[1], 1)), bool) for i in ids]
    choice = np.full((n_frames, len(scene.slots), n_cams), -1)
    if not combos:
        return choice
    n_views = np.array([sum(i >= 0 for i in k) for k in combos])[:, None]
    areas = scene.area_costs(centre[..., :2]) if scene.mode == "players" else None
    frames = np.arange(n_frames)
    for s in range(len(scene.slots)):
        # most views, then inside the area rather than within its margin, then the least error
        outside = areas[..., s] > 0 if areas is not None else 0.0
        score = np.where(agree, n_views - (outside + np.minimum(error, 1.0)) / 4, -np.inf)
        if areas is not None:
            score[areas[..., s] > scene.area_margin_m] = -np.inf
        for k, combo in enumerate(combos):
            clash = np.any([taken[c][:, i] for c, i in enumerate(combo) if i >= 0], axis=0)
            if foreign is not None:
                clash |= np.any([_foreign_view(foreign[c], ids[c][:, i], s, scene)
                                 for c, i in enumerate(combo) if i >= 0], axis=0)
            score[k, clash] = -np.inf
        best = np.argmax(score, axis=0)
        found = np.isfinite(score[best, frames])
        choice[found, s] = np.array(combos)[best[found]]
        for c in range(n_cams):
            mine = found & (choice[:, s, c] >= 0)
            taken[c][mine, choice[mine, s, c]] = True
    if scene.mode == "subjects" and len(scene.slots) > 1:
        choice = _stable_labels(choice, centre, combos)
    return choice


def _foreign_view(foreign: np.ndarray, tracklet: np.ndarray, slot: int, scene: Scene) -> np.ndarray:
    """(F,) whether a camera's person (tracklet ids (F,), -1 where none) is foreign to the slot
    (foreign (S, T) of foreign_tracklets; subjects mode: one pooled row for every slot)."""
    rows = foreign[slot] if scene.mode == "players" else foreign[0]
    return (tracklet >= 0) & rows[np.maximum(tracklet, 0)] if len(rows) else np.zeros(len(tracklet), bool)


def foreign_tracklets(choice: np.ndarray, ids: list[np.ndarray], pooled: bool = False) -> list[np.ndarray]:
    """Per camera, (S, T) True where tracklet t of the camera is someone other than slot s's person:
    seen beside the person the camera gave the slot (same frame, another tracklet) in more frames than
    the camera gave the slot tracklet t. choice (F, S, C) as associate's; ids[c] (F, P) the tracklet id
    of each of camera c's people (-1 where none).

    pooled (subjects mode, whose slots are labels set afterwards): one row (1, T), the slots taken together:
    t is foreign when it was seen unchosen beside a chosen person in more frames than it was chosen for any
    slot. Slot by slot, a subject whose frames the labels split between two slots was seen beside each
    slot's other occupant more often than chosen for it, so foreign to every slot and lost (the lab
    walkthrough's far player: found in 25 of 8,442 frames once the twin's limbs swapped at PoseFix's
    rates)."""
    out = []
    for c, person in enumerate(ids):
        n_ids = int(person.max(initial=-1)) + 1
        groups = [list(range(choice.shape[1]))] if pooled else [[s] for s in range(choice.shape[1])]
        mine = np.zeros((len(groups), n_ids), int)
        beside = np.zeros((len(groups), n_ids), int)
        for g, slots in enumerate(groups):
            given = choice[:, slots, c]  # (F, slots) the camera's person index given each slot
            got = (given >= 0).any(axis=1)
            at = np.nonzero(given >= 0)  # only where a person was given: a camera may have none at all
            chosen = np.full(given.shape, -1)
            chosen[at] = person[at[0], given[at]]
            chosen = chosen[got]  # (frames with any, slots) the tracklets given
            np.add.at(mine[g], chosen[chosen >= 0], 1)
            present = person[got]
            unchosen = (present >= 0) & ~(present[:, :, None] == chosen[:, None, :]).any(axis=2)
            np.add.at(beside[g], present[unchosen], 1)
        out.append(beside > mine)
    return out


def _stable_labels(choice: np.ndarray, centre: np.ndarray, combos: list[tuple]) -> np.ndarray:
    """choice (F, S, C) with each frame's subjects reordered to continue the labels of the frames before:
    the Hungarian match of their 3D centres to each label's last centre (a new label is the first free)."""
    index = {combo: k for k, combo in enumerate(combos)}
    out = np.full_like(choice, -1)
    last = np.full((choice.shape[1], 3), np.nan)
    for f in range(len(choice)):
        found = [s for s in range(choice.shape[1]) if (choice[f, s] >= 0).any()]
        if not found:
            continue
        where = np.array([centre[index[tuple(choice[f, s])], f] for s in found])
        cost = np.linalg.norm(where[:, None] - last[None], axis=-1)
        cost = np.where(np.isfinite(cost), cost, NEW_LABEL_M + np.arange(len(last))[None])
        rows, cols = linear_sum_assignment(cost)
        out[f, cols] = choice[f, [found[r] for r in rows]]
        last[cols] = where[rows]
    return out
