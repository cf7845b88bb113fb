"""OpenPose people of one camera followed from frame to frame, limb swaps undone, as a 2D pose table.

Which person is which player (or subject) is decided later, across cameras, by geometry
(`perception.association`): this stage keeps every person it sees, bystanders too.

Tracklets (`link_tracklets`): every person is followed from frame to frame by
scipy.optimize.linear_sum_assignment on the distance between a detection's joints and each track's
last joints (the nearer of the same joint and its mirror, so limb swaps do not break a track), in torso
lengths measured in the image (`torso_pixels`), within a gate that widens while a track is unseen
(TRACK_*). The table's `person` column is the tracklet id, unique within the camera.

Left/right limb swaps (`fix_limb_swaps`): OpenPose now and then reports a whole arm, leg or foot on
the wrong side for a frame. Each limb of each frame is compared with the raw limbs of the two frames
before and after on the same tracklet: a swapped limb lies closer to the opposite side's joints of its
neighbours. The limb is swapped back when most neighbours say so. Deciding from the raw neighbours (not
the corrected previous frame) keeps one wrong decision from spreading along the track; swaps that
last many frames look continuous in 2D and are left to the multi-view 3D stage.
"""

import os
import re

import numpy as np
import pandas as pd
from scipy.optimize import linear_sum_assignment

from pingpong.frames import BODY25, MODEL_JOINTS
from pingpong.io.openpose_json import N_JOINTS, pose_keypoints, read_keypoints_folder, reader_layout
from pingpong.perception.schemas import POSE2D_VALUES, joint_columns

MIN_CONFIDENCE = 0.3  # config perception.pose_min_confidence: joints below are gaps

J = {name: i for i, name in enumerate(BODY25)}
# Pairs of joints a torso length apart (neck to mid-hip, each shoulder to its hip): a person's pixel scale.
TORSO_PAIRS = ((J["Neck"], J["MidHip"]), (J["RShoulder"], J["RHip"]), (J["LShoulder"], J["LHip"]))
TORSO_PER_HEIGHT = 0.3  # a torso is about this share of the height of a standing person's detected joints
TRACK_GATE = 0.5  # torso lengths a person's joints may move in one frame
TRACK_GATE_PER_FRAME = 0.1  # and more per frame since the track was last seen,
TRACK_GATE_MAX = 1.5  # up to this
TRACK_MEMORY_FRAMES = 50  # 0.5 s; a person unseen for longer starts a new tracklet
MIRROR = [BODY25.index({"R": "L", "L": "R"}[n[0]] + n[1:]) if n[0] in "RL" else i
          for i, n in enumerate(BODY25)]  # each joint's left/right counterpart (itself on the midline)
# Limbs OpenPose swaps as a whole: (right joints, left joints).
LIMBS = (((J["RShoulder"], J["RElbow"], J["RWrist"]), (J["LShoulder"], J["LElbow"], J["LWrist"])),
         ((J["RHip"], J["RKnee"], J["RAnkle"]), (J["LHip"], J["LKnee"], J["LAnkle"])),
         ((J["RBigToe"], J["RSmallToe"], J["RHeel"]), (J["LBigToe"], J["LSmallToe"], J["LHeel"])))
SWAP_NEIGHBOURS = (-2, -1, 1, 2)  # frames compared with to detect a swapped limb


def torso_pixels(keypoints: np.ndarray) -> np.ndarray:
    """(F, P) a torso's pixel length for each detection (F, P, 25, 3): the median of its measured torso
    pairs, else TORSO_PER_HEIGHT of its detected joints' height, else the median of all; 1 if none."""
    xy = np.where(keypoints[..., 2:] > 0, keypoints[..., :2], np.nan)
    pairs = np.stack([np.linalg.norm(xy[..., a, :] - xy[..., b, :], axis=-1) for a, b in TORSO_PAIRS], -1)
    scale = nanmedian_last(np.where(pairs > 0, pairs, np.nan))
    with np.errstate(invalid="ignore"):
        height = np.fmax.reduce(xy[..., 1], axis=-1) - np.fmin.reduce(xy[..., 1], axis=-1)
    scale = np.where(np.isfinite(scale), scale, np.where(height > 0, TORSO_PER_HEIGHT * height, np.nan))
    known = np.isfinite(scale)
    return np.where(known, scale, np.median(scale[known]) if known.any() else 1.0)


def nanmedian_last(values: np.ndarray) -> np.ndarray:
    """np.nanmedian over the last axis, NaN where all are NaN, without its warning and ~10x faster
    on the small arrays of one frame (np.nanmedian goes through masked arrays there)."""
    ordered = np.sort(values, axis=-1)  # NaN sort last
    count = np.isfinite(values).sum(axis=-1, keepdims=True)
    low = np.take_along_axis(ordered, np.maximum(count - 1, 0) // 2, axis=-1)
    high = np.take_along_axis(ordered, count // 2 - (count == 0), axis=-1)
    return np.where(count > 0, (low + high) / 2, np.nan)[..., 0]


def link_tracklets(keypoints: np.ndarray, scales: np.ndarray) -> np.ndarray:
    """(F, P) tracklet id of every detection (-1 where none): people linked frame to frame.

    Every person is tracked, bystanders included, so that a player's track competes with the
    bystander's own track for the bystander's detections (and loses) instead of taking them over
    while the player is unseen. A track keeps each joint's last pixel position; a detection's
    distance to it is the median over shared joints of the distance to the same joint or its
    mirror (so a limb swap costs nothing), in torso lengths: scales (F, P), each detection's torso
    length in pixels (torso_pixels); linear_sum_assignment matches detections to tracks within a gate.
    """
    present = (keypoints[..., 2] > 0).any(axis=-1)
    xy = np.where(keypoints[..., 2:] > 0, keypoints[..., :2], np.nan)
    ids = np.full(present.shape, -1)
    track_xy = np.zeros((0, 25, 2))
    track_scale, last_seen = np.zeros(0), np.zeros(0, int)
    for f in range(len(keypoints)):
        people = np.flatnonzero(present[f])
        active = np.flatnonzero(f - last_seen <= TRACK_MEMORY_FRAMES)
        here, there = xy[f, people, None], track_xy[None, active]  # (P, 1, 25, 2), (1, T, 25, 2)
        moved = np.fmin(np.linalg.norm(here - there, axis=-1),
                        np.linalg.norm(here - there[:, :, MIRROR], axis=-1))
        moved = nanmedian_last(moved) / track_scale[active]
        gate = np.minimum(TRACK_GATE + TRACK_GATE_PER_FRAME * (f - last_seen[active] - 1), TRACK_GATE_MAX)
        allowed = moved <= gate
        rows, cols = linear_sum_assignment(np.where(allowed, moved, 1e9))
        track = np.full(len(people), -1)
        keep = allowed[rows, cols]
        track[rows[keep]] = active[cols[keep]]
        new = track < 0  # people not seen before
        track[new] = len(last_seen) + np.arange(new.sum())
        track_xy = np.concatenate([track_xy, np.full((new.sum(), 25, 2), np.nan)])
        track_scale = np.concatenate([track_scale, np.ones(new.sum())])
        last_seen = np.concatenate([last_seen, np.zeros(new.sum(), int)])
        ids[f, people] = track
        seen = np.isfinite(xy[f, people])
        track_xy[track] = np.where(seen, xy[f, people], track_xy[track])
        track_scale[track] = scales[f, people]
        last_seen[track] = f
    return ids


def tracklet_lanes(ids: np.ndarray) -> np.ndarray:
    """(F, P) lane of every detection (-1 where none), lanes being few: tracklets (ids (F, P)) share a
    lane when they never overlap in time and lie more than max(SWAP_NEIGHBOURS) frames apart, so a
    lane's neighbouring frames hold the same person (fix_limb_swaps compares with them)."""
    lanes = np.full(ids.shape, -1)
    frame_of, person_of = np.nonzero(ids >= 0)
    tracklet = ids[frame_of, person_of]
    if len(tracklet) == 0:
        return lanes
    first = np.full(tracklet.max() + 1, len(ids))
    last = np.full(tracklet.max() + 1, -1)
    np.minimum.at(first, tracklet, frame_of)
    np.maximum.at(last, tracklet, frame_of)
    lane_end, lane_of = [], np.full(len(first), -1)
    for k in np.argsort(first, kind="stable"):
        free = [lane for lane, end in enumerate(lane_end) if first[k] - end > max(SWAP_NEIGHBOURS)]
        lane = free[0] if free else len(lane_end)
        lane_end[lane:lane + 1] = [last[k]]
        lane_of[k] = lane
    lanes[frame_of, person_of] = lane_of[tracklet]
    return lanes


def tracked_people(keypoints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every detected person of keypoints (F, P, J, 3) in the reader's layout (`openpose_json.reader_layout`:
    BODY_25's 25 joints first) followed over time, limb swaps undone. People are followed on BODY_25's
    joints; the model's others (BODY_25B's UpperNeck and HeadTop, Halpe's Head: on the midline, which no
    limb swap moves) go with their person.

    Returns people (F, L, J, 3) and their tracklet ids (F, L), -1 (and zeros) where a lane is empty."""
    keypoints = np.asarray(keypoints, float)
    body = keypoints[..., :N_JOINTS, :]
    ids = link_tracklets(body, torso_pixels(body))
    lanes = tracklet_lanes(ids)
    n_lanes = lanes.max(initial=-1) + 1  # 0 where nobody is ever seen
    people = np.zeros((len(keypoints), n_lanes, *keypoints.shape[2:]))
    track = np.full((len(keypoints), n_lanes), -1)
    f, p = np.nonzero(lanes >= 0)
    people[f, lanes[f, p]] = keypoints[f, p]
    track[f, lanes[f, p]] = ids[f, p]
    return fix_limb_swaps(people), track


def fix_limb_swaps(players: np.ndarray) -> np.ndarray:
    """A copy of players (F, S, J, 3) (BODY_25's joints first) with single-frame left/right limb swaps
    undone (see module doc)."""
    players = np.asarray(players, float)
    out = players.copy()
    xy = np.where(players[..., 2:] > 0, players[..., :2], np.nan)
    n_frames = len(players)
    for right, left in LIMBS:
        limb = xy[:, :, list(right + left)]  # (F, S, 6, 2): right joints then left joints
        mirrored = xy[:, :, list(left + right)]
        votes_swap = np.zeros(players.shape[:2], int)
        votes_keep = np.zeros(players.shape[:2], int)
        for step in SWAP_NEIGHBOURS:
            frames = np.arange(max(0, -step), min(n_frames, n_frames - step))
            neighbour, neighbour_mirrored = limb[frames + step], mirrored[frames + step]
            # each joint seen here and on both sides of the neighbour: distance to its own side vs the other
            own = np.linalg.norm(limb[frames] - neighbour, axis=-1)
            other = np.linalg.norm(limb[frames] - neighbour_mirrored, axis=-1)
            usable = np.isfinite(own) & np.isfinite(other)
            gain = np.where(usable, own - other, 0.0).sum(axis=-1)  # > 0: the swapped reading fits better
            votes_swap[frames] += usable.any(axis=-1) & (gain > 0)
            votes_keep[frames] += usable.any(axis=-1) & (gain <= 0)
        f, s = np.nonzero(votes_swap > votes_keep)
        f, s = f[:, None], s[:, None]
        out[f, s, list(right + left)] = players[f, s, list(left + right)]
    return out


def model_joints(players: np.ndarray, min_confidence: float = MIN_CONFIDENCE, joints=MODEL_JOINTS,
                 layout=BODY25) -> np.ndarray:
    """(F, S, J, 3) [u px, v px, confidence] of the joints (names in layout; the 8 model joints by default)
    of players (F, S, len(layout), 3); u, v are NaN (a gap) where the confidence is below min_confidence or
    the joint was not detected (confidence 0 is kept)."""
    joints = np.asarray(players, float)[:, :, [layout.index(name) for name in joints]].copy()
    confidence = joints[..., 2]
    joints[(confidence < min_confidence) | (confidence <= 0), :2] = np.nan
    return joints


def pose2d_table(folder: str | os.PathLike, time_ns: np.ndarray, min_confidence: float = MIN_CONFIDENCE,
                 model: str = "BODY_25", pattern: str | re.Pattern | None = None) -> pd.DataFrame:
    """Every person's keypoints from one camera's OpenPose folder, one row per (frame, person).

    time_ns (F,): the camera's frame times; the folder must hold frames 0..F-1, files named by
    pattern (`openpose_json.layout_patterns`: any known layout by default) holding keypoints of the
    declared model (`openpose_json.KEYPOINT_MODELS`). Columns: time_ns, person (the tracklet id, -1 on
    the one row of a frame with nobody), and per keypoint of the model in its order, named as
    `openpose_json.pose_keypoints` names it (the 8 model joints among them): {name}_u, _v (distorted
    pixels) and _conf (OpenPose's confidence, 0 where not detected); gaps have u, v NaN. Rows are ordered
    by time, then person.
    """
    time_ns = np.asarray(time_ns, np.int64)
    # one file per frame time: extra or missing files are named there
    _, keypoints = read_keypoints_folder(folder, model, pattern, n_frames=len(time_ns))
    people, track = tracked_people(keypoints)
    names, layout = pose_keypoints(model), reader_layout(model)
    joints = model_joints(people, min_confidence, names, layout)  # (F, L, J, 3)
    f, lane = np.nonzero(track >= 0)
    empty = np.flatnonzero((track < 0).all(axis=1))  # a row of gaps keeps such a frame on the clock
    frame = np.concatenate([f, empty])
    person = np.concatenate([track[f, lane], np.full(len(empty), -1)])
    gaps = model_joints(np.zeros((len(empty), 1, len(layout), 3)), joints=names, layout=layout)[:, 0]
    rows = np.concatenate([joints[f, lane], gaps]).reshape(len(frame), -1)
    order = np.lexsort((person, frame))
    table = pd.DataFrame(rows[order], columns=list(joint_columns(names, POSE2D_VALUES)))
    table.insert(0, "person", person[order])
    table.insert(0, "time_ns", time_ns[frame[order]])
    return table
