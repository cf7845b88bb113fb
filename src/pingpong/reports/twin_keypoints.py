"""The twin's 2D keypoints against its truth: what its simulated detector got wrong, beside the published
figures its rates come from (reports/tables/twin_keypoints.md).

Each camera's OpenPose people are matched, frame by frame, to the players' projected true joints (the
median distance over their reported joints under MATCH_SHARE of the player's scale); a person matched to
no player is a false person (the bystander, the spectator). On the players' matched detections, per
joint: the error against the projected truth (px, as a share of the player's joints' height in the image
and of COCO's object scale s), misses (a joint in the image the JSON leaves at 0) and left/right swaps (a
reported joint nearer the other side's true joint, both in plain view, SWAP_APART_SIGMAS apart),
for joints in plain view and hidden ones (behind the own trunk or a nearer person) apart.
"""

import os
import re

import numpy as np

from pingpong.common.camera import Camera
from pingpong.frames import BODY25
from pingpong.io.openpose_json import keypoints_filename
from pingpong.perception.pose2d import MIRROR
from pingpong.twin.openpose_sim import (
    COCO_SIGMAS,
    LIMB_SWAPS,
    KeypointErrors,
    _occluded,
    object_scale,
    projected_people,
    self_hidden,
)

PLAYERS = ("near", "far")
MATCH_SHARE = 0.5  # a detection is a player's when its median joint distance is under this share of s
MATCH_CHUNK = 2048  # frames measured at once: every figure is a frame's, and their arrays stay in cache
# A swap is told from noise only where both sides are in plain view and their true joints lie this many of
# the joint's COCO sigmas of s apart (a detector erring as COCO's annotators then calls 0.02 % of its
# unswapped joints swapped: 2.5 sigma, 3.5 standard deviations along the line between them).
SWAP_APART_SIGMAS = 5.0
# The joints of the table, left and right pooled: the COCO keypoints of the body (not the face or feet).
JOINT_GROUPS = {"nose": ("Nose",), "shoulder": ("RShoulder", "LShoulder"), "elbow": ("RElbow", "LElbow"),
                "wrist": ("RWrist", "LWrist"), "hip": ("RHip", "LHip"), "knee": ("RKnee", "LKnee"),
                "ankle": ("RAnkle", "LAnkle")}
SIDED = np.array([MIRROR[j] != j for j in range(25)])
SWAPPED_JOINTS = np.isin(np.arange(25), [j for limb in LIMB_SWAPS for side in limb for j in side])
# The median of the 2D error's length when its RMS is 1 (a circular Gaussian: sqrt(ln 2)).
MEDIAN_PER_RMS = np.sqrt(np.log(2.0))


# A person's keypoints in the twin's JSON (`io.openpose_json.format_keypoints_json`: 75 numbers, no nesting)
POSE_VALUES = re.compile(rb'"pose_keypoints_2d":\[([^\]]*)\]')
VALUES_PER_PERSON = 75


def read_twin_keypoints(folder, basename: str, n_frames: int) -> np.ndarray:
    """(F, K, 25, 3) keypoints of the twin's own OpenPose folder (rule twin_openpose: frames 0..n_frames-1,
    each file named `keypoints_filename(basename, frame)` in `format_keypoints_json`'s layout), as
    `io.openpose_json.read_keypoints_folder` reads them (people in file order, padded with zeros to the most
    in any frame), without its cost: one regex over all files and one number parse (NumPy's, correctly
    rounded as Python's float) instead of a JSON document, a path and a check per file and person, and
    without the declared-model vote a lab's files need (the twin writes BODY_25). 16 camera-sessions of
    the default run: ~250,000 files. Errors name the folder; tests hold it equal to the general reader."""
    names = [keypoints_filename(basename, frame) for frame in range(n_frames)]
    listed = {name for name in os.listdir(folder) if name.endswith("_keypoints.json")}
    if listed != set(names):
        raise ValueError(f"{folder}: {len(listed)} keypoints files, expected {basename}'s frames "
                         f"0..{n_frames - 1} ({len(set(names) - listed)} missing, "
                         f"{len(listed - set(names))} others)")
    prefix = os.path.join(folder, "")
    texts = [_read_bytes(prefix + name) for name in names]
    counts = np.array([text.count(b'"pose_keypoints_2d"') for text in texts])
    people = POSE_VALUES.findall(b"\n".join(texts))
    values = np.fromstring(b",".join(people).decode(), sep=",") if people else np.zeros(0)
    if len(people) != counts.sum() or len(values) != VALUES_PER_PERSON * len(people) \
            or any(person.count(b",") != VALUES_PER_PERSON - 1 for person in people):
        raise ValueError(f"{folder}: not the twin's OpenPose JSON ({len(people)} pose arrays of "
                         f"{counts.sum()} people, {len(values)} numbers; expected {VALUES_PER_PERSON} each)")
    out = np.zeros((n_frames, counts.max(initial=0), 25, 3))
    frame = np.repeat(np.arange(n_frames), counts)
    slot = np.arange(len(people)) - np.repeat(np.cumsum(counts) - counts, counts)
    out[frame, slot] = values.reshape(-1, 25, 3)
    return out


def _read_bytes(path: str) -> bytes:
    """A file's bytes by the system calls alone: half the time of open().read() on small files."""
    fd = os.open(path, os.O_RDONLY)
    try:
        chunks = [os.read(fd, 1 << 16)]
        while len(chunks[-1]) == 1 << 16:
            chunks.append(os.read(fd, 1 << 16))
    finally:
        os.close(fd)
    return chunks[0] if len(chunks) == 1 else b"".join(chunks)


def _true_views(camera: Camera, truth_joints: np.ndarray) -> dict:
    """Projected truth of the players and the bystander (P, n, 25, ...): pixels, inside the image, hidden,
    object scale s and the joints' height in the image (px)."""
    present, px, depth = projected_people(camera, truth_joints)
    f = camera.K[0, 0]
    with np.errstate(invalid="ignore"):
        inside = (depth > 0.1) & (px[..., 0] >= 0) & (px[..., 0] < camera.width) & (px[..., 1] >= 0) \
            & (px[..., 1] < camera.height)
        height = np.fmax.reduce(px[..., 1], axis=-1) - np.fmin.reduce(px[..., 1], axis=-1)
    return {"present": present, "px": px, "inside": inside, "scale": object_scale(px), "height": height,
            "hidden": _occluded(px, depth, f) | self_hidden(px, depth, f)}


def match_people(detections: np.ndarray, true_px: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """(F, K) the index of the true person each detection (F, K, 25, 3) is, -1 for none (false people and
    padding): the nearest by median distance over its reported joints, under MATCH_SHARE of that person's
    scale (F, P); each true person taken once per frame, nearest first. Frame by frame, so in chunks of
    MATCH_CHUNK frames (arrays that stay in the cache)."""
    out = np.full(detections.shape[:2], -1)
    for first in range(0, len(detections), MATCH_CHUNK):
        chunk = slice(first, first + MATCH_CHUNK)
        out[chunk] = _match_chunk(detections[chunk], true_px[chunk], scale[chunk])
    return out


def _match_chunk(detections: np.ndarray, true_px: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """match_people on a chunk of frames. The median distance is the lower median of the reported joints'
    distances (the root of the lower median of the squares: the same value, the root being monotonic)."""
    reported = detections[..., 2] > 0
    dx = detections[:, :, None, :, 0] - true_px[:, None, :, :, 0]  # (F, K, P, 25)
    dy = detections[:, :, None, :, 1] - true_px[:, None, :, :, 1]
    squared = np.where(reported[:, :, None], dx * dx + dy * dy, np.nan)
    with np.errstate(invalid="ignore"):
        count = np.isfinite(squared).sum(-1)
        squared.sort(axis=-1)
        median = np.sqrt(np.take_along_axis(squared, np.maximum(count - 1, 0)[..., None] // 2, -1)[..., 0])
        ok = median < MATCH_SHARE * scale[:, None]
    cost = np.where(ok, median, np.inf)
    out = np.full(detections.shape[:2], -1)
    for _ in range(min(cost.shape[1], cost.shape[2])):
        flat = cost.reshape(len(cost), -1)
        best = np.argmin(flat, axis=1)
        frames = np.flatnonzero(np.isfinite(flat[np.arange(len(cost)), best]))
        k, p = np.divmod(best[frames], cost.shape[2])
        out[frames, k] = p
        cost[frames, k, :] = np.inf
        cost[frames, :, p] = np.inf
    return out


def _distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|a - b| over a last axis of x, y (np.linalg.norm's value: the root of dx dx + dy dy), x and y apart."""
    dx, dy = a[..., 0] - b[..., 0], a[..., 1] - b[..., 1]
    return np.sqrt(dx * dx + dy * dy)


def camera_errors(camera: Camera, detections: np.ndarray, truth_joints: np.ndarray, names: list[str]) -> dict:
    """One camera's keypoints against the truth of one session: per-joint arrays over the players'
    matched detections (the near player's rows, then the far player's), and the false-people frames.

    detections (F, K, 25, 3) as read from the JSON, frame by frame with truth_joints (P, F, 25, 3) of the
    people named in names (the players and any bystander). Every figure is a frame's, so the frames go in
    chunks of MATCH_CHUNK (arrays that stay in the cache)."""
    players = [names.index(p) for p in PLAYERS]
    rows = {p: {k: [] for k in ("error", "mirror_error", "reported", "inside", "hidden", "scale", "height",
                                "apart", "both_clear", "confidence")} for p in players}
    false_frames = []
    for first in range(0, len(detections), MATCH_CHUNK):
        chunk = slice(first, first + MATCH_CHUNK)
        false_frames.append(_chunk_errors(camera, detections[chunk], truth_joints[:, chunk], players, rows))
    out = {k: np.concatenate([part for p in players for part in rows[p][k]]) for k in rows[players[0]]}
    out["false_frames"] = np.concatenate(false_frames)
    out["frames"] = len(detections)
    return out


def _chunk_errors(camera: Camera, detections: np.ndarray, truth_joints: np.ndarray, players: list[int],
                  rows: dict) -> np.ndarray:
    """camera_errors on a chunk of frames: appends each player's arrays to rows[player]; returns the
    chunk's false-people frames."""
    view = _true_views(camera, truth_joints)
    true_px = np.moveaxis(view["px"], 0, 1)  # (F, P, 25, 2)
    who = match_people(detections, true_px, view["scale"].T)
    reported_any = (detections[..., 2] > 0).any(-1)
    for p in players:
        f, k = np.nonzero(who == p)
        got = detections[f, k]
        truth_px = view["px"][p, f]
        mine = rows[p]
        mine["error"].append(_distance(got, truth_px))
        mine["mirror_error"].append(_distance(got, truth_px[:, MIRROR]))
        mine["apart"].append(_distance(truth_px, truth_px[:, MIRROR]))
        mine["reported"].append(got[..., 2] > 0)
        mine["confidence"].append(got[..., 2])
        mine["inside"].append(view["inside"][p, f])
        mine["hidden"].append(view["hidden"][p, f])
        clear = view["inside"][p, f] & ~view["hidden"][p, f]
        mine["both_clear"].append(clear & clear[:, MIRROR])
        mine["scale"].append(np.repeat(view["scale"][p, f, None], 25, 1))
        mine["height"].append(np.repeat(view["height"][p, f, None], 25, 1))
    return (reported_any & ~np.isin(who, players)).any(axis=1)


def _apart(e: dict, ids=slice(None)) -> np.ndarray:
    """Where a swap can be told from noise: a sided joint in plain view, as its other side, the two far
    apart in the image. e's per-joint arrays hold the joints ids (all 25 by default)."""
    return SIDED[ids] & e["both_clear"] & (e["apart"] > SWAP_APART_SIGMAS * COCO_SIGMAS[ids] * e["scale"])


def _swapped(e: dict, apart: np.ndarray) -> np.ndarray:
    return apart & e["reported"] & (e["mirror_error"] < e["error"])


def joint_rows(per_camera: list[dict], errors: KeypointErrors) -> list[dict]:
    """One row per joint group over every camera: the 2D error of plain-view and hidden joints, misses and
    swaps, beside COCO's sigma and the error the configured detector should make. Each group's joints are
    taken out of every camera's arrays before they are joined (a twelfth of the data a group)."""
    rows = []
    for group, joints in JOINT_GROUPS.items():
        ids = [BODY25.index(j) for j in joints]
        e = {k: np.concatenate([c[k][:, ids] for c in per_camera]) for k in per_camera[0]
             if k not in ("false_frames", "frames")}
        apart = _apart(e, ids)
        swapped = _swapped(e, apart)
        inside = e["inside"]
        clear = inside & e["reported"] & ~swapped & ~e["hidden"]
        hidden = inside & e["reported"] & ~swapped & e["hidden"]
        sigma = float(COCO_SIGMAS[ids[0]])
        rows.append({
            "joint": group, "coco_sigma": sigma,
            "expected_median_per_s": errors.sigma_scale * sigma * MEDIAN_PER_RMS,
            "median_per_s": _median(e["error"][clear] / e["scale"][clear]),
            "median_px": _median(e["error"][clear]), "p90_px": _quantile(e["error"][clear], 0.9),
            "median_per_height_pct": 100 * _median(e["error"][clear] / e["height"][clear]),
            "hidden_median_px": _median(e["error"][hidden]),
            "confidence_clear": _median(e["confidence"][clear]),
            "confidence_hidden": _median(e["confidence"][hidden]),
            "confidence_swapped": _median(e["confidence"][inside & swapped]),
            "hidden_pct": 100 * _share(e["hidden"][inside]),
            # in plain view as its other side: a swap would trade a lost hidden joint into view
            "miss_visible_pct": 100 * _share(~e["reported"][inside & e["both_clear"]]),
            "expected_miss_visible_pct": 100 * errors.miss_rate,
            "miss_hidden_pct": 100 * _share(~e["reported"][inside & e["hidden"]]),
            "expected_miss_hidden_pct": 100 * errors.hidden_miss,
            "swap_pct": 100 * _share(swapped[inside & e["reported"] & apart]),
            "expected_swap_pct": 100 * expected_swap_share(errors) if SWAPPED_JOINTS[ids[0]] else np.nan,
            "n": int(inside.sum())})
    return rows


# Ronchi & Perona 2017's localization errors, as their released code classes a matched detection's keypoints
# (coco-analyze, pycocotools/cocoanalyze.py, COCOanalyze._find_kpt_errors): the keypoint similarity to a true
# keypoint is ks = exp(-d^2 / (2 s^2 (2 sigma)^2)) (s^2 the person's area, sigma COCO's); of every true
# keypoint in the image, the own, its left/right counterpart and other people's, the most similar decides:
# good (own, ks > 0.85: within 1.14 sigma s), jitter (own, 0.5 <= ks < 0.85: 1.14-2.35 sigma s), inversion
# (the own counterpart, ks >= 0.5), swap (another person's, ks >= 0.5), miss (ks < 0.5 to all: more than
# 2.35 sigma s from every one). Over annotated keypoints (visible or occluded); ties go to the own keypoint.
RP_GOOD, RP_JITTER = 0.85, 0.5
COCO_KEYPOINTS = [BODY25.index(j) for j in ("Nose", "LEye", "REye", "LEar", "REar", "LShoulder", "RShoulder",
                                            "LElbow", "RElbow", "LWrist", "RWrist", "LHip", "RHip", "LKnee",
                                            "RKnee", "LAnkle", "RAnkle")]
# The published rates beside the twin's: PoseFix (Moon, Chang & Lee 2019, CVPR; its released
# main/gen_batch.py, synthesize_pose) draws each COCO keypoint's error class with these probabilities, which
# its author took from Ronchi & Perona 2017's statistics of the CMU (OpenPose) and G-RMI detectors on COCO
# (PoseFix_RELEASE issue 37; their Fig. 6 itself was not retrieved): a person with more than 10 annotated
# keypoints, not in a crowd. Per COCO keypoint (nose, eyes, ears, shoulders, elbows, wrists, hips, knees,
# ankles, left and right alike); the table shows their mean over the 17.
POSEFIX_2019 = {  # class -> per keypoint group probability
    "jitter": {"nose": 0.10, "eyes": 0.15, "ears": 0.15, "shoulders": 0.15, "elbows": 0.15, "wrists": 0.15,
               "hips": 0.20, "knees": 0.10, "ankles": 0.10},
    "inversion": {"nose": 0.01, "eyes": 0.01, "ears": 0.01, "shoulders": 0.03, "elbows": 0.03, "wrists": 0.03,
                  "hips": 0.06, "knees": 0.06, "ankles": 0.06},
    "swap": {"nose": 0.01, "eyes": 0.01, "ears": 0.01, "shoulders": 0.06, "elbows": 0.06, "wrists": 0.06,
             "hips": 0.03, "knees": 0.03, "ankles": 0.03},
    "miss": {"nose": 0.02, "eyes": 0.02, "ears": 0.02, "shoulders": 0.05, "elbows": 0.10, "wrists": 0.10,
             "hips": 0.10, "knees": 0.10, "ankles": 0.05},
}
COCO_GROUP_SIZES = {"nose": 1, "eyes": 2, "ears": 2, "shoulders": 2, "elbows": 2, "wrists": 2, "hips": 2,
                    "knees": 2, "ankles": 2}  # the 17 COCO keypoints


def posefix_shares() -> dict[str, float]:
    """Each class's share of the 17 COCO keypoints (%) under POSEFIX_2019, good the rest."""
    shares = {kind: 100 * sum(COCO_GROUP_SIZES[g] * p for g, p in groups.items()) / 17
              for kind, groups in POSEFIX_2019.items()}
    return {"good": 100 - sum(shares.values()), **shares}


def ronchi_perona_rows(per_camera: list[dict], errors: KeypointErrors) -> list[dict]:
    """The players' COCO keypoints inside the image (every camera) classed by Ronchi & Perona's definitions
    (good, jitter, inversion, swap, miss: shares of the keypoints, %), each beside the twin's error it
    maps to and the configured rate behind it, and the published figure (POSEFIX_2019). A keypoint
    the JSON leaves at 0, 0, 0 lies far from every joint: a miss, as OpenPose's would in their evaluation.
    The twin's detector takes no joint from another person (swap: none by construction)."""
    *counts, total = (int(n) for n in np.sum([_ronchi_perona_counts(c) for c in per_camera], axis=0))
    shares = dict(zip(("good", "jitter", "inversion", "swap", "miss"), counts, strict=True))
    limb = f"swap_rate {errors.swap_rate:g} x swap_frames {errors.swap_frames:g} / {len(LIMB_SWAPS)} limbs"
    twin = {
        "good": ("a joint within 1.14 COCO sigmas of s of its truth", f"sigma_scale {errors.sigma_scale:g}"),
        "jitter": ("the 2D noise (COCO's sigmas of s), blur and the hidden joints' larger noise",
                   f"sigma_scale {errors.sigma_scale:g}, hidden_scale {errors.hidden_scale:g}, "
                   f"exposure_s {errors.exposure_s:g}"),
        "inversion": ("a left/right swap of an arm, leg or foot",
                      f"{limb} = {100 * expected_swap_share(errors):.2g} % of a limb joint's frames"),
        "swap": ("none: the twin's detector never takes another person's joint", "none"),
        "miss": ("a lost joint (0, 0, 0): visible ones at miss_rate, hidden ones at hidden_miss",
                 f"miss_rate {errors.miss_rate:g}, hidden_miss {errors.hidden_miss:g}")}
    published = posefix_shares()
    return [{"error (Ronchi & Perona 2017)": kind, "twin_pct": 100 * _ratio(count, total),
             "published_pct": published[kind], "the twin's error": twin[kind][0],
             "config (twin.keypoint_errors)": twin[kind][1], "n": total} for kind, count in shares.items()]


def _ronchi_perona_counts(e: dict) -> list[int]:
    """One camera-session's COCO keypoints inside the image counted by Ronchi & Perona's classes (good,
    jitter, inversion, swap, miss) and in all, their similarity thresholds taken as thresholds of
    q = d^2 / (s^2 kappa^2) (ks = exp(-q / 2))."""
    inside = e["inside"][:, COCO_KEYPOINTS]
    norm = e["scale"][:, COCO_KEYPOINTS] ** 2 * (2 * COCO_SIGMAS[COCO_KEYPOINTS]) ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        own = (e["error"][:, COCO_KEYPOINTS] ** 2 / norm)[inside]
        other_side = (e["mirror_error"][:, COCO_KEYPOINTS] ** 2 / norm)[inside]
    good_q, jitter_q = -2 * np.log(RP_GOOD), -2 * np.log(RP_JITTER)  # ks > 0.85, ks >= 0.5
    own_best = own <= other_side  # ties go to the own keypoint
    good = own_best & (own < good_q)
    jitter = own_best & (own >= good_q) & (own <= jitter_q)
    inversion = ~own_best & (other_side <= jitter_q)
    miss = np.fmin(own, other_side) > jitter_q
    return [int(good.sum()), int(jitter.sum()), int(inversion.sum()), 0, int(miss.sum()), len(own)]


def expected_swap_share(errors: KeypointErrors) -> float:
    """The share of frames a given limb joint is swapped in: swaps start at swap_rate per detection, last
    swap_frames on average and take one of the LIMB_SWAPS limbs (overlaps neglected)."""
    return errors.swap_rate * errors.swap_frames / len(LIMB_SWAPS)


def camera_rows(cams: list[str], per_camera: list[dict]) -> list[dict]:
    """Per camera: the share of frames with a false person (someone matched to no player), of the
    players' joints missed and swapped. Shares as counts over every session of the camera (the same
    values as the mean of the joined arrays, without joining them)."""
    rows = []
    for cam in sorted(set(cams)):
        mine = [c for name, c in zip(cams, per_camera, strict=True) if name == cam]
        counts = np.sum([_camera_counts(c) for c in mine], axis=0)
        frames, false, inside, missed, hidden, separable, swapped = (int(n) for n in counts)
        rows.append({"camera": cam, "frames": frames, "false_people_frames_pct": 100 * _ratio(false, frames),
                     "miss_pct": 100 * _ratio(missed, inside), "hidden_pct": 100 * _ratio(hidden, inside),
                     "swap_pct": 100 * _ratio(swapped, separable)})
    return rows


def _camera_counts(e: dict) -> list[int]:
    """One camera-session's counts for camera_rows: frames, frames with a false person, joints inside the
    image, of them missed and hidden, reported and separable from their other side, of them swapped."""
    apart = _apart(e)
    separable = e["inside"] & e["reported"] & apart
    return [len(e["false_frames"]), int(e["false_frames"].sum()), int(e["inside"].sum()),
            int((~e["reported"] & e["inside"]).sum()), int((e["hidden"] & e["inside"]).sum()),
            int(separable.sum()), int((_swapped(e, apart) & separable).sum())]


def _ratio(count: int, total: int) -> float:
    return count / total if total else np.nan


def _median(x: np.ndarray) -> float:
    return float(np.median(x)) if len(x) else np.nan


def _quantile(x: np.ndarray, q: float) -> float:
    return float(np.quantile(x, q)) if len(x) else np.nan


def _share(x: np.ndarray) -> float:
    return float(np.mean(x)) if len(x) else np.nan
