"""OpenPose people of one camera assigned to the two players, limb swaps undone, as a 2D pose table.

Side assignment (`assign_sides`), in three steps:
1. Where each person stands, from the calibrated camera: the ray through each of its core joints
   (nose, neck, shoulders, hips, knees, ankles) meets the horizontal plane at that joint's typical
   height for a player (TYPICAL_HEIGHTS); the median of these points is its floor position. Its
   region cost for a side is the distance (m) from the area behind that table end where a player
   stands (PLAYER_AREA_*); a bystander beside the table or far behind is outside both areas.
2. Tracklets: every person (bystanders too) is followed from frame to frame by
   scipy.optimize.linear_sum_assignment on the distance between a detection's joints and each
   track's last joints (the nearer of the same joint and its mirror, so limb swaps do not break a
   track), in torso lengths, within a gate that widens while a track is unseen (TRACK_*).
3. Sides: per side, the tracklets that typically stand within REGION_MARGIN_M of its area compete;
   the set of tracklets that never overlap in time with the largest total weight (frames in the
   area count 1, those outside less) is chosen by weighted interval scheduling. So an extra
   person near an area loses to the player who is there at the same time, for the whole of its
   tracklet, including frames where the player is not detected; people far from both areas are
   never assigned. A person who stands near a player's area only while that player is away
   cannot be told from the player by geometry and is assigned.

Left/right limb swaps (`fix_limb_swaps`): OpenPose now and then reports a whole arm, leg or foot on
the wrong side for a frame. Each limb of each frame is compared with the raw limbs of the two frames
before and after: a swapped limb lies closer to the opposite side's joints of its neighbours.
The limb is swapped back when most neighbours say so. Deciding from the raw neighbours (not the
corrected previous frame) keeps one wrong decision from spreading along the track; swaps that
last many frames look continuous in 2D and are left to the multi-view 3D stage.
"""

import os
import re

import numpy as np
import pandas as pd
from scipy.optimize import linear_sum_assignment

from pingpong.common.camera import Camera
from pingpong.frames import BODY25, MODEL_JOINT_IDS, TABLE_HALF_LENGTH
from pingpong.io.openpose_json import read_keypoints_folder
from pingpong.perception.schemas import MODEL_JOINT_COLUMNS

PLAYERS = ("near", "far")  # index 0: the player at +y, 1: at -y
PLAYER_SIGNS = (1.0, -1.0)
MIN_CONFIDENCE = 0.3  # config perception.pose_min_confidence: joints below are gaps

J = {name: i for i, name in enumerate(BODY25)}
# Table-frame height (m) of core joints of an adult in the ready stance (table top z = 0, floor -0.76).
TYPICAL_HEIGHTS = {J["Nose"]: 0.65, J["Neck"]: 0.5, J["RShoulder"]: 0.5, J["LShoulder"]: 0.5,
                   J["MidHip"]: 0.05, J["RHip"]: 0.05, J["LHip"]: 0.05, J["RKnee"]: -0.35,
                   J["LKnee"]: -0.35, J["RAnkle"]: -0.68, J["LAnkle"]: -0.68}
# Where a player stands (m, table frame): |x| below the half width, |y| between the two bounds
# on their side. Bystanders stand beside the table, |x| >= 1.56 m, |y| <= 1.37 m.
PLAYER_AREA_HALF_WIDTH = 1.5
PLAYER_AREA_Y = (TABLE_HALF_LENGTH, TABLE_HALF_LENGTH + 3.0)
REGION_MARGIN_M = 0.3  # a tracklet typically further than this from a side's area is never that player
TORSO_M = 0.5  # neck to mid-hip, sets the pixel scale of a track
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



def floor_positions(keypoints: np.ndarray, camera: Camera) -> np.ndarray:
    """(F, P, 2) table-frame (x, y) where each detected person stands (NaN when none of its core
    joints is detected or their rays miss the planes of their typical heights)."""
    joints = np.array(list(TYPICAL_HEIGHTS))
    heights = np.array(list(TYPICAL_HEIGHTS.values()))
    core = keypoints[..., joints, :]  # (F, P, J, 3)
    pixels = camera.undistort_pixels(core[..., :2].reshape(-1, 2))
    rays = np.column_stack([pixels, np.ones(len(pixels))]) @ np.linalg.inv(camera.K).T @ camera.R
    rays = rays.reshape(*core.shape[:-1], 3)
    centre = camera.center
    with np.errstate(divide="ignore", invalid="ignore"):
        reach = (heights - centre[2]) / rays[..., 2]  # ray parameter at the joint's plane
    points = centre[:2] + reach[..., None] * rays[..., :2]
    valid = (core[..., 2] > 0) & (reach > 0)
    points[~valid] = np.nan
    out = np.full((*keypoints.shape[:2], 2), np.nan)
    seen = valid.any(axis=-1)
    out[seen] = np.nanmedian(points[seen], axis=-2)
    return out


def region_costs(floor_xy: np.ndarray) -> np.ndarray:
    """(..., 2) distance (m) of floor positions (..., 2) from the near and far players' areas; inf if NaN."""
    dx = np.maximum(np.abs(floor_xy[..., 0]) - PLAYER_AREA_HALF_WIDTH, 0.0)
    costs = []
    for sign in PLAYER_SIGNS:
        y = sign * floor_xy[..., 1]
        dy = np.maximum(PLAYER_AREA_Y[0] - y, 0.0) + np.maximum(y - PLAYER_AREA_Y[1], 0.0)
        costs.append(np.hypot(dx, dy))
    return np.nan_to_num(np.stack(costs, axis=-1), nan=np.inf)


def torso_pixels(floor_xy: np.ndarray, camera: Camera) -> np.ndarray:
    """Expected pixel length of a torso at floor positions (..., 2): focal length * TORSO_M / depth."""
    neck = np.concatenate([floor_xy, np.full((*floor_xy.shape[:-1], 1), TYPICAL_HEIGHTS[J["Neck"]])], -1)
    depth = camera.depth(neck.reshape(-1, 3)).reshape(floor_xy.shape[:-1])
    return camera.K[0, 0] * TORSO_M / np.maximum(depth, 0.1)


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
    mirror (so a limb swap costs nothing), in torso lengths: scales (F, P), a torso's pixel length
    where each person stands, linear_sum_assignment matches detections to tracks within a gate.
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


def best_tracklets(first: np.ndarray, last: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Indices of the tracklets, no two overlapping in time (frames first..last), of the largest total
    weight: weighted interval scheduling by dynamic programming."""
    order = np.argsort(last, kind="stable")
    first, last, weight = first[order], last[order], weight[order]
    before = np.searchsorted(last, first, side="left")  # tracklets [0, before) end before each starts
    best = np.zeros(len(order) + 1)
    for i in range(len(order)):
        best[i + 1] = max(best[i], weight[i] + best[before[i]])
    chosen, i = [], len(order)
    while i > 0:
        if weight[i - 1] + best[before[i - 1]] > best[i - 1]:
            chosen.append(order[i - 1])
            i = before[i - 1]
        else:
            i -= 1
    return np.array(chosen[::-1], int)


def assign_sides(keypoints: np.ndarray, camera: Camera) -> np.ndarray:
    """(F, 2, 25, 3) people of each frame assigned to ('near', 'far'); zeros where a player is not seen.

    keypoints: (F, P, 25, 3) [x px, y px, confidence] in any person order, zero-padded.
    """
    keypoints = np.asarray(keypoints, float)
    out = np.zeros((len(keypoints), 2, 25, 3))
    if keypoints.shape[1] == 0:
        return out
    floor_xy = floor_positions(keypoints, camera)
    regions = region_costs(floor_xy)  # (F, P, 2)
    scales = torso_pixels(floor_xy, camera)
    scales = np.where(np.isfinite(scales), scales, np.nanmedian(scales) if np.isfinite(scales).any() else 1.0)
    ids = link_tracklets(keypoints, scales)
    n_tracklets = ids.max() + 1
    frame_of, person_of = np.nonzero(ids >= 0)
    tracklet = ids[frame_of, person_of]
    first = np.full(n_tracklets, len(keypoints))
    last = np.zeros(n_tracklets, int)
    np.minimum.at(first, tracklet, frame_of)
    np.maximum.at(last, tracklet, frame_of)
    for side in range(2):
        region = regions[frame_of, person_of, side]
        typical = pd.Series(region).groupby(tracklet).median().reindex(range(n_tracklets)).to_numpy()
        # each frame counts fully inside the area, less the further out it stands
        weight = np.bincount(tracklet, np.clip(1 - region / REGION_MARGIN_M, 0, 1), n_tracklets)
        candidates = np.flatnonzero(typical <= REGION_MARGIN_M)
        for k in candidates[best_tracklets(first[candidates], last[candidates], weight[candidates])]:
            mine = tracklet == k
            out[frame_of[mine], side] = keypoints[frame_of[mine], person_of[mine]]
    return out


def fix_limb_swaps(players: np.ndarray) -> np.ndarray:
    """A copy of players (F, S, 25, 3) with single-frame left/right limb swaps undone (see module doc)."""
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


def model_joints(players: np.ndarray, min_confidence: float = MIN_CONFIDENCE) -> np.ndarray:
    """(F, S, 8, 3) [u px, v px, confidence] of the model joints; u, v are NaN (a gap) where the
    confidence is below min_confidence or the joint was not detected (confidence 0 is kept)."""
    joints = np.asarray(players, float)[:, :, list(MODEL_JOINT_IDS)].copy()
    confidence = joints[..., 2]
    joints[(confidence < min_confidence) | (confidence <= 0), :2] = np.nan
    return joints


def pose2d_table(folder: str | os.PathLike, camera: Camera, time_ns: np.ndarray,
                 min_confidence: float = MIN_CONFIDENCE, model: str = "BODY_25",
                 pattern: str | re.Pattern | None = None) -> pd.DataFrame:
    """Both players' model joints from one camera's OpenPose folder, one row per (frame, player).

    time_ns (F,): the camera's frame times; the folder must hold frames 0..F-1, files named by
    pattern (`openpose_json.layout_patterns`: any known layout by default) holding keypoints of the
    declared model (`openpose_json.KEYPOINT_MODELS`), mapped by name to BODY_25. Columns: time_ns,
    player ('near'/'far'), and per model joint j (BODY_25 index): j{j:02d}_u, _v (distorted pixels)
    and _conf (OpenPose's confidence, 0 where not detected); gaps have u, v NaN.
    """
    time_ns = np.asarray(time_ns, np.int64)
    frames, keypoints = read_keypoints_folder(folder, model, pattern)
    if not np.array_equal(frames, np.arange(len(time_ns))):
        missing = np.setdiff1d(np.arange(len(time_ns)), frames)
        raise ValueError(f"{folder}: OpenPose frames {frames[:1].tolist()}..{frames[-1:].tolist()} "
                         f"({len(frames)} files), expected frames 0..{len(time_ns) - 1} for the camera's "
                         f"{len(time_ns)} frame times; missing {missing[:5].tolist()}")
    joints = model_joints(fix_limb_swaps(assign_sides(keypoints, camera)), min_confidence)  # (F, 2, 8, 3)
    rows = joints.transpose(1, 0, 2, 3).reshape(2 * len(time_ns), -1)
    table = pd.DataFrame(rows, columns=list(MODEL_JOINT_COLUMNS))
    table.insert(0, "player", np.repeat(PLAYERS, len(time_ns)))
    table.insert(0, "time_ns", np.tile(time_ns, 2))
    return table
