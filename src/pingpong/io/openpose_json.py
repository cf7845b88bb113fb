"""OpenPose-family per-frame JSON (--write_json): read in any of four keypoint models, written as BODY_25.

One file per frame, {"version":1.3,"people":[{"person_id":[-1],"pose_keypoints_2d":[x,y,c]*K,
"face_keypoints_2d":[],"hand_left_keypoints_2d":[],"hand_right_keypoints_2d":[],"pose_keypoints_3d":[],
"face_keypoints_3d":[],"hand_left_keypoints_3d":[],"hand_right_keypoints_3d":[]}]}, compact, pixels of
the source image; an undetected joint is 0,0,0. K is the model's keypoint count, which the file does not
name: the caller declares the model (KEYPOINT_MODELS) and the reader maps its joints by name into its
layout (`reader_layout`: BODY_25's 25 joints, then the model's keypoints BODY_25 lacks). Files are named
by one of LAYOUTS (or a caller's regex); the writer writes BODY_25 in OpenPose's own layout, as the
digital twin needs.

Read as real tools write it: a person without keypoints ({}) is no person; values are checked where they
enter (finite numbers, confidences in [0, 1], K triples); a folder is checked against the video's frame
count (the extra or missing files named) and its declared model against the others of K keypoints
(`check_declared_model`: BODY_25B declared BODY_25 would read silently with the wrong joints). Every
refusal is a KeypointsFileError naming the file (and the person), malformed or too deeply nested JSON
included.
"""

import json
import logging
import os
import re
import warnings
from pathlib import Path

import numpy as np

from pingpong.common.atomic import write_text_atomic
from pingpong.frames import BODY25
from pingpong.io.guards import check_int64, parse_text

N_JOINTS = 25
EMPTY_FIELDS = ("face_keypoints_2d", "hand_left_keypoints_2d", "hand_right_keypoints_2d", "pose_keypoints_3d",
                "face_keypoints_3d", "hand_left_keypoints_3d", "hand_right_keypoints_3d")

# Keypoint names in each model's output order.
KEYPOINT_MODELS = {
    # OpenPose doc/02_output.md and src/openpose/pose/poseParameters.cpp POSE_BODY_25_BODY_PARTS
    "BODY_25": BODY25,
    # openpose_train's BODY_25B (experimental_models), poseParameters.cpp POSE_BODY_25B_BODY_PARTS;
    # UpperNeck (below the chin) and HeadTop are not BODY_25's Neck, which it lacks, as it lacks MidHip
    "BODY_25B": ("Nose", "LEye", "REye", "LEar", "REar", "LShoulder", "RShoulder", "LElbow", "RElbow",
                 "LWrist", "RWrist", "LHip", "RHip", "LKnee", "RKnee", "LAnkle", "RAnkle", "UpperNeck",
                 "HeadTop", "LBigToe", "LSmallToe", "LHeel", "RBigToe", "RSmallToe", "RHeel"),
    # OpenPose's 18-keypoint COCO: doc/02_output.md and poseParameters.cpp POSE_COCO_BODY_PARTS
    "COCO": ("Nose", "Neck", "RShoulder", "RElbow", "RWrist", "LShoulder", "LElbow", "LWrist", "RHip",
             "RKnee", "RAnkle", "LHip", "LKnee", "LAnkle", "REye", "LEye", "REar", "LEar"),
    # AlphaPose's Halpe 26: Fang-Haoshu/Halpe-FullBody README, "26 body keypoints" (its "Rknee" is RKnee)
    "HALPE_26": ("Nose", "LEye", "REye", "LEar", "REar", "LShoulder", "RShoulder", "LElbow", "RElbow",
                 "LWrist", "RWrist", "LHip", "RHip", "LKnee", "RKnee", "LAnkle", "RAnkle", "Head", "Neck",
                 "Hip", "LBigToe", "RBigToe", "LSmallToe", "RSmallToe", "LHeel", "RHeel"),
}
# A model's name for a BODY_25 joint where it differs: Halpe's Hip is the pelvis centre, BODY_25's MidHip.
BODY25_NAME = {"Hip": "MidHip"}
# BODY_25 joints a model may lack, derived as the midpoint of two it has (both detected, confidence the
# lower of the two): BODY_25's Neck and MidHip lie about there, and pose2d's floor positions use them.
MIDPOINTS = {"Neck": ("RShoulder", "LShoulder"), "MidHip": ("RHip", "LHip")}

# Per-frame file names: (template, regex of the whole name whose one group is the frame number).
LAYOUTS = {
    "openpose": ("{name}_{frame:012d}_keypoints.json", r".*_(\d{12})_keypoints\.json"),  # OpenPose's own
    "dotted": ("{name}.{frame}.json", r".*\.(\d+)\.json"),  # e.g. {name}.{frame:05d}.json, any digit count
}


class KeypointsFileError(ValueError):
    """A keypoints file or folder that does not hold what the declared model and layout promise."""


def keypoints_filename(basename: str, frame: int) -> str:
    return f"{basename}_{frame:012d}_keypoints.json"


# OpenPose prints floats with 6 significant digits and integral zeros as 0 ("%.6g" does both); one
# format string for a person's 75 numbers formats them in one call, ~4x faster than number by number.
_POSE_FORMAT = ",".join(["%.6g"] * (N_JOINTS * 3))
_EMPTY = ",".join(f'"{field}":[]' for field in EMPTY_FIELDS)


def format_keypoints_json(people: np.ndarray) -> str:
    """The JSON text of one frame's people (P, 25, 3) [x, y, confidence]."""
    rows = np.asarray(people, float).reshape(-1, N_JOINTS * 3) + 0.0  # + 0.0: -0 prints as 0
    persons = [f'{{"person_id":[-1],"pose_keypoints_2d":[{_POSE_FORMAT % tuple(row)}],{_EMPTY}}}'
               for row in rows.tolist()]
    return '{"version":1.3,"people":[' + ",".join(persons) + "]}"


def write_keypoints_json(folder: str | os.PathLike, basename: str, frame: int, people: np.ndarray) -> Path:
    """Write one frame's file (atomically) and return its path."""
    path = Path(folder) / keypoints_filename(basename, frame)
    write_text_atomic(path, format_keypoints_json(people))
    return path


def model_keypoint_names(model: str) -> tuple[str, ...]:
    if model not in KEYPOINT_MODELS:
        raise ValueError(f"unknown keypoint model {model!r}; expected one of {', '.join(KEYPOINT_MODELS)}")
    return KEYPOINT_MODELS[model]


def pose_keypoints(model: str) -> tuple[str, ...]:
    """The declared model's keypoints in its order, each named as BODY_25 names the same joint (BODY25_NAME:
    Halpe's Hip is MidHip) or, where BODY_25 has none, by the model's own name (BODY_25B's UpperNeck and
    HeadTop, Halpe's Head): the joints the pose tables carry, so that a joint's name means one thing in
    every model."""
    return tuple(BODY25_NAME.get(name, name) for name in model_keypoint_names(model))


def reader_layout(model: str) -> tuple[str, ...]:
    """The joints the reader gives for the model, by name: BODY_25's 25 (pose2d's tracking works on those),
    then the model's keypoints BODY_25 lacks, in the model's order."""
    return BODY25 + tuple(name for name in pose_keypoints(model) if name not in BODY25)


def to_reader_layout(keypoints: np.ndarray, model: str) -> np.ndarray:
    """(..., L, 3) keypoints (..., K, 3) in the model's order, mapped by joint name into reader_layout(model);
    a BODY_25 joint the model lacks is 0, 0, 0 (absent) unless derived (MIDPOINTS)."""
    names, layout = pose_keypoints(model), reader_layout(model)
    keypoints = np.asarray(keypoints, float)
    out = np.zeros((*keypoints.shape[:-2], len(layout), 3))
    out[..., [layout.index(name) for name in names], :] = keypoints
    for joint, pair in MIDPOINTS.items():
        if joint not in names:
            ends = out[..., [BODY25.index(name) for name in pair], :]  # (..., 2, 3)
            both = (ends[..., 2] > 0).all(axis=-1)
            out[..., BODY25.index(joint), :2] = np.where(both[..., None], ends[..., :2].mean(axis=-2), 0.0)
            out[..., BODY25.index(joint), 2] = np.where(both, ends[..., 2].min(axis=-1), 0.0)
    return out


def _count_hint(count: int, model: str) -> str:
    """What a pose value count would fit instead of the declared model."""
    fits = [name for name, names in KEYPOINT_MODELS.items() if 3 * len(names) == count and name != model]
    if not fits:
        return ""
    if set(fits) & {"BODY_25", "BODY_25B"}:
        return (f"; {count} values fit {' or '.join(fits)} (BODY_25 and BODY_25B cannot be told apart "
                "by count: declare the model the data were made with)")
    return f"; {count} values fit {' or '.join(fits)}: declare that model"


# the keys of a person in OpenPose's JSON (and of the markerless tools that write its format)
OPENPOSE_PERSON_KEYS = {"person_id", *(f"{part}_keypoints_{d}d" for d in (2, 3)
                                       for part in ("pose", "face", "hand_left", "hand_right"))}
OPENPOSE_LAYOUT = '{"version":..,"people":[{"pose_keypoints_2d":[x,y,c]*K,..}]}'
_NUMBERS = {int, float}  # JSON numbers as json.loads gives them; bool, str and None are not


def _pose_values(path: Path, index: int, person, model: str) -> np.ndarray | None:
    """One person's (K, 3) keypoints of the declared model, checked; None for a person with no
    keypoints ({}, or an absent, null or empty pose_keypoints_2d), as markerless-capture tools write
    for a frame where nobody is associated."""
    names = KEYPOINT_MODELS[model]
    where = f"{path}: person {index}"
    if not isinstance(person, dict):
        raise KeypointsFileError(f"{where} is {type(person).__name__} {person!r:.40}, expected an object "
                                 '{"pose_keypoints_2d":[x,y,c]*K,..}')
    pose = person.get("pose_keypoints_2d")
    if pose is None or pose == []:
        strange = sorted(set(person) - OPENPOSE_PERSON_KEYS)  # a misspelt or damaged key, not an empty person
        if strange:
            warnings.warn(f"{where} has no pose_keypoints_2d but keys {strange} that OpenPose does not "
                          "write: read as no person", stacklevel=2)
        return None
    if not isinstance(pose, list):
        raise KeypointsFileError(f"{where}: pose_keypoints_2d is {type(pose).__name__}, expected a list of "
                                 f"{3 * len(names)} numbers (x, y, confidence per {model} keypoint)")
    if not set(map(type, pose)) <= _NUMBERS:
        k = next(k for k, value in enumerate(pose) if type(value) not in _NUMBERS)
        raise KeypointsFileError(f"{where}: pose_keypoints_2d value {k} is {pose[k]!r} "
                                 f"({type(pose[k]).__name__}), expected a number")
    if len(pose) % 3 or len(pose) != 3 * len(names):
        triples = "" if len(pose) % 3 == 0 else ", not a multiple of 3 (x, y, confidence per keypoint)"
        raise KeypointsFileError(f"{where} has {len(pose)} pose_keypoints_2d values{triples}, expected "
                                 f"{3 * len(names)} ({len(names)} keypoints x 3) for {model}"
                                 f"{_count_hint(len(pose), model)}")
    try:
        values = np.array(pose, float).reshape(len(names), 3)
    except OverflowError:  # an integer of hundreds of digits
        values = np.array([float(v) if abs(v) < 1e308 else np.inf for v in pose]).reshape(len(names), 3)
    bad = ~np.isfinite(values)  # NaN, Infinity and numbers beyond a double (1e999) all parse as such
    bad_confidence = ~bad[:, 2] & ((values[:, 2] < 0) | (values[:, 2] > 1))
    if bad.any():
        k, c = np.argwhere(bad)[0]
        raise KeypointsFileError(f"{where}: keypoint {k} ({names[k]}) has {'xyc'[c]} = {values[k, c]}, "
                                 "expected a finite number")
    if bad_confidence.any():
        k = int(np.argmax(bad_confidence))
        raise KeypointsFileError(f"{where}: keypoint {k} ({names[k]}) has confidence {values[k, 2]:g}, "
                                 "expected one in [0, 1]")
    return values


def read_model_keypoints(path: str | os.PathLike, model: str = "BODY_25") -> np.ndarray:
    """People (P, K, 3) of one file in the declared model's own keypoint order, values checked (finite,
    confidence in [0, 1], K keypoints); persons without keypoints left out; errors name the file."""
    return _read_people(path, model)[0]


def _read_people(path: str | os.PathLike, model: str) -> tuple[np.ndarray, int]:
    """read_model_keypoints' people, and how many persons without keypoints it left out."""
    path = Path(path)
    names = model_keypoint_names(model)
    doc = parse_text(path, json.loads, KeypointsFileError, "an OpenPose keypoints JSON", OPENPOSE_LAYOUT)
    people = doc.get("people") if isinstance(doc, dict) else None
    if not isinstance(people, list):
        wrong = (f"the document is {type(doc).__name__}" if not isinstance(doc, dict) else "no people"
                 if people is None else f"people is {type(people).__name__}, not a list")
        raise KeypointsFileError(f"{path}: not an OpenPose keypoints JSON ({wrong}); "
                                 f"expected {OPENPOSE_LAYOUT}")
    poses = [_pose_values(path, i, person, model) for i, person in enumerate(people)]
    found = [pose for pose in poses if pose is not None]
    return np.array(found).reshape(-1, len(names), 3), len(poses) - len(found)


def read_keypoints_json(path: str | os.PathLike, model: str = "BODY_25") -> np.ndarray:
    """People (P, L, 3) in the reader's layout (`reader_layout`) of one file of the declared model
    (`read_model_keypoints`)."""
    return to_reader_layout(read_model_keypoints(path, model), model)


def layout_patterns(pattern: str | re.Pattern | None = None) -> dict[str, re.Pattern]:
    """The file name patterns to look for: every layout (None), one named layout, or a caller's regex
    (matched against the whole file name) with exactly one group, the frame number."""
    if pattern is None:
        return {name: re.compile(regex) for name, (_, regex) in LAYOUTS.items()}
    if isinstance(pattern, str) and pattern in LAYOUTS:
        return {pattern: re.compile(LAYOUTS[pattern][1])}
    try:
        compiled = re.compile(pattern)
    except re.error as exc:
        raise ValueError(f"file pattern {pattern!r}: not a layout ({', '.join(LAYOUTS)}) "
                         f"nor a valid regex ({exc})") from exc
    if compiled.groups != 1:
        raise ValueError(f"file pattern {compiled.pattern!r} has {compiled.groups} groups; expected one, "
                         "the frame number (or a layout name: " + ", ".join(LAYOUTS) + ")")
    return {"pattern": compiled}


def _describe(patterns: dict[str, re.Pattern]) -> str:
    return " or ".join(f"{LAYOUTS[name][0]} (regex {p.pattern})" if name in LAYOUTS else f"regex {p.pattern}"
                       for name, p in patterns.items())


def _matching_names(folder: Path, patterns: dict[str, re.Pattern]) -> tuple[re.Pattern, list[str]]:
    """The one pattern the folder's file names follow and the names that match it."""
    names = sorted(p.name for p in folder.iterdir() if p.is_file())
    found = {layout: [] for layout in patterns}
    for name in names:
        layout = next((layout for layout, p in patterns.items() if p.fullmatch(name)), None)
        if layout is not None:
            found[layout].append(name)
    used = [layout for layout, matched in found.items() if matched]
    if not used:
        jsons = [name for name in names if name.lower().endswith(".json")] or names
        seen = f"found e.g. {jsons[0]!r} ({len(names)} files in all)" if names else "the folder is empty"
        raise KeypointsFileError(f"{folder}: no per-frame keypoints files; expected names "
                                 f"{_describe(patterns)}; {seen}")
    if len(used) > 1:
        examples = ", ".join(f"{layout}: e.g. {found[layout][0]!r}" for layout in used)
        raise KeypointsFileError(f"{folder}: per-frame files of {len(used)} layouts mixed ({examples}); "
                                 "keep one layout per folder or declare the pattern")
    return patterns[used[0]], found[used[0]]


def _frame_number(path: Path, pattern: re.Pattern) -> int:
    number = pattern.fullmatch(path.name).group(1)
    if number is None or not number.isdigit():
        raise KeypointsFileError(f"{path}: the group of file pattern {pattern.pattern!r} holds {number!r}, "
                                 "expected the frame number (digits)")
    return check_int64(int(number), KeypointsFileError, f"{path}: frame number", "a frame number")


def list_frame_files(folder: str | os.PathLike,
                     pattern: str | re.Pattern | None = None) -> list[tuple[int, Path]]:
    """(frame, path) of a folder's per-frame files in frame order (the number in the name, numerically).

    Files of other names are ignored; none matching, two layouts mixed, two files of one frame or
    a frame missing between the first and the last are errors.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise KeypointsFileError(f"{folder}: not a folder (expected one of per-frame keypoints JSON files)")
    matched, names = _matching_names(folder, layout_patterns(pattern))
    entries = sorted((_frame_number(folder / name, matched), folder / name) for name in names)
    frames = np.array([frame for frame, _ in entries])
    steps = np.diff(frames)
    if (steps == 0).any():
        frame = frames[np.argmax(steps == 0)]
        same = ", ".join(path.name for f, path in entries if f == frame)
        raise KeypointsFileError(f"{folder}: frame {frame} has more than one file ({same}); expected one "
                                 "per frame")
    if (steps > 1).any():
        k = np.argmax(steps > 1)
        raise KeypointsFileError(f"{folder}: frame {frames[k] + 1} missing (files of frames {frames[k]} then "
                                 f"{frames[k + 1]}); expected every frame from {frames[0]} to {frames[-1]}")
    return entries


SHOWN = 5  # files an error names, of many


def _name_of_frame(example: Path, pattern: re.Pattern, frame: int) -> str:
    """The file name frame would have, following an existing file's (zero-padded if its number is)."""
    match = pattern.fullmatch(example.name)
    start, end = match.span(1)
    digits = match.group(1)
    number = f"{frame:0{len(digits)}d}" if digits.startswith("0") and len(digits) > 1 else str(frame)
    return example.name[:start] + number + example.name[end:]


def _listed(names: list[str], count: int) -> str:
    """The first few of count names, and how many more."""
    return ", ".join(names) + (f" and {count - len(names)} more" if count > len(names) else "")


def check_frame_count(folder: str | os.PathLike, entries: list[tuple[int, Path]], n_frames: int,
                      pattern: str | re.Pattern | None = None) -> list[tuple[int, Path]]:
    """The entries (`list_frame_files`) of frames 0..n_frames-1, one file per frame of the video. Files past
    the video's last frame are left out with a warning naming them (markerless-capture tools can write one
    more than a video's frames); any other mismatch is an error naming the extra and missing files (the
    first few of each) and both counts."""
    frames = [frame for frame, _ in entries]
    if frames[:n_frames] == list(range(n_frames)):
        if len(frames) > n_frames:
            extra = [path.name for _, path in entries[n_frames:]]
            warnings.warn(f"{folder}: {len(extra)} keypoints files past the video's last frame "
                          f"{n_frames - 1} left out: {_listed(extra[:SHOWN], len(extra))}", stacklevel=2)
        return entries[:n_frames]
    extra = [path.name for frame, path in entries if frame >= n_frames]
    missing = np.setdiff1d(np.arange(n_frames), frames)
    pattern = next(p for p in layout_patterns(pattern).values() if p.fullmatch(entries[0][1].name))
    named = [_name_of_frame(entries[0][1], pattern, int(frame)) for frame in missing[:SHOWN]]
    told = [f"{len(extra)} extra: {_listed(extra[:SHOWN], len(extra))}"] if extra else []
    told += [f"{len(missing)} missing: {_listed(named, len(missing))}"] if len(missing) else []
    raise KeypointsFileError(f"{folder}: {len(entries)} keypoints files (frames {frames[0]}..{frames[-1]}) "
                             f"for a video of {n_frames} frames; expected frames 0..{n_frames - 1}, one file "
                             f"per frame; {'; '.join(told)}")


def read_keypoints_folder(folder: str | os.PathLike, model: str = "BODY_25",
                          pattern: str | re.Pattern | None = None,
                          n_frames: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Frame numbers (F,) and keypoints (F, P_max, L, 3), the reader's layout (`reader_layout`), of a
    folder's per-frame files.

    Frames in the order of their numbers (`list_frame_files`); with n_frames (the video's frame count)
    they must be 0..n_frames-1 (`check_frame_count`). People are padded with zeros (confidence 0 =
    absent) to the largest count in any frame, in file order. The declared model must be the most
    plausible of those with as many keypoints (`check_declared_model`).
    """
    entries = list_frame_files(folder, pattern)
    if n_frames is not None:
        entries = check_frame_count(folder, entries, n_frames, pattern)
    frames = np.array([frame for frame, _ in entries], np.int64)
    read = [_read_people(path, model) for _, path in entries]
    per_frame, empty = [people for people, _ in read], [n for _, n in read]
    if sum(empty):
        first = entries[next(i for i, n in enumerate(empty) if n)][1].name
        logging.info("%s: %d people without keypoints ({}) in %d files read as nobody (the first in %s)",
                     folder, sum(empty), sum(map(bool, empty)), first)
    most = max((len(people) for people in per_frame), default=0)
    raw = np.zeros((len(entries), most, len(KEYPOINT_MODELS[model]), 3))
    for i, people in enumerate(per_frame):
        raw[i, :len(people)] = people
    check_declared_model(raw, model, [path for _, path in entries])
    return frames, to_reader_layout(raw, model)


# The declared model's plausibility. BODY_25 and BODY_25B files both hold 75 values a person, so only the
# content tells them apart: the same points joined by the declared model's bones make a short skeleton
# (bones join neighbouring points), by another model's bones a long one (a "knee-ankle" bone from a knee
# to an eye). Bone lengths do not depend on which way a person faces, lies or bends, where the order of
# joints up the image or the left/right symmetry (projected limbs foreshorten unequally) would.
# Bones by BODY_25 names, none to Neck or MidHip (midpoints in models that lack them, see MIDPOINTS).
SKELETON = (("Nose", "REye"), ("Nose", "LEye"), ("REye", "REar"), ("LEye", "LEar"),
            ("RShoulder", "LShoulder"), ("RShoulder", "RElbow"), ("RElbow", "RWrist"),
            ("LShoulder", "LElbow"), ("LElbow", "LWrist"), ("RShoulder", "RHip"), ("LShoulder", "LHip"),
            ("RHip", "LHip"), ("RHip", "RKnee"), ("RKnee", "RAnkle"), ("LHip", "LKnee"), ("LKnee", "LAnkle"),
            ("RAnkle", "RHeel"), ("RHeel", "RBigToe"), ("RBigToe", "RSmallToe"), ("LAnkle", "LHeel"),
            ("LHeel", "LBigToe"), ("LBigToe", "LSmallToe"))
MIN_BONES = 5  # detected bones a person needs to be compared
MIN_PEOPLE = 10  # people a folder needs before its model is judged
# The declared model is refused when another's skeleton is shorter for this share of the people, by this
# median factor. On the tiny twin run's BODY_25 people (3 cameras, 12,000-13,500 people each) the wrong
# reading, either way round, is shorter for 0-8 % of them and longer by 1.8-2.1x (median); on simulated
# people lying, bending or crouching, for 0-1.3 % and by 1.8-2.8x (tests/test_openpose_io.py).
MODEL_VOTE_SHARE = 0.8
MODEL_RATIO = 1.25


def _bones(model: str, other: str) -> list[tuple[int, int]]:
    """BODY_25 indices of the SKELETON bones whose ends both models name."""
    named = set(pose_keypoints(model)) & set(pose_keypoints(other))
    return [(BODY25.index(a), BODY25.index(b)) for a, b in SKELETON if a in named and b in named]


def skeleton_lengths(raw: np.ndarray, model: str, bones: list[tuple[int, int]]) -> np.ndarray:
    """(...) mean length of a person's detected bones (BODY_25 index pairs) when raw (..., K, 3) is read
    as model, over the diagonal of the box around its detected points; NaN under MIN_BONES bones."""
    body = to_reader_layout(raw, model)
    ends = body[..., [a for a, _ in bones], :], body[..., [b for _, b in bones], :]
    seen = (ends[0][..., 2] > 0) & (ends[1][..., 2] > 0)
    length = np.where(seen, np.linalg.norm(ends[0][..., :2] - ends[1][..., :2], axis=-1), 0.0)
    points = np.where(raw[..., 2:] > 0, raw[..., :2], np.nan)
    with warnings.catch_warnings():  # people with no detected point: all-NaN boxes, NaN results
        warnings.simplefilter("ignore", RuntimeWarning)
        diagonal = np.linalg.norm(np.nanmax(points, axis=-2) - np.nanmin(points, axis=-2), axis=-1)
        mean = length.sum(axis=-1) / seen.sum(axis=-1)
        return np.where((seen.sum(axis=-1) >= MIN_BONES) & (diagonal > 0), mean / diagonal, np.nan)


def model_comparison(raw: np.ndarray, model: str, other: str) -> tuple[int, float, float, np.ndarray]:
    """(people compared, share whose skeleton is shorter read as other, median factor by which it is,
    (...) bool: each person's skeleton shorter by MODEL_RATIO read as other) of people raw (..., K, 3)."""
    bones = _bones(model, other)
    declared, alternative = skeleton_lengths(raw, model, bones), skeleton_lengths(raw, other, bones)
    both = np.isfinite(declared) & np.isfinite(alternative)
    ratio = declared[both] / alternative[both]
    if not both.any():
        return 0, 0.0, 1.0, both
    strongly = np.zeros_like(both)
    strongly[both] = ratio >= MODEL_RATIO
    return int(both.sum()), float(np.mean(ratio > 1)), float(np.median(ratio)), strongly


def check_declared_model(raw: np.ndarray, model: str, paths: list[Path]) -> None:
    """An error naming a file and the likely model when people raw (F, P, K, 3), the files' (paths, one a
    frame) in the declared model's order, are clearly less plausible as that model than as another model
    of K keypoints (see SKELETON): over MIN_PEOPLE people at least, most shorter read as the other."""
    for other in KEYPOINT_MODELS:
        if other == model or len(KEYPOINT_MODELS[other]) != len(KEYPOINT_MODELS[model]):
            continue
        n, share, ratio, strongly = model_comparison(raw, model, other)
        if n >= MIN_PEOPLE and share >= MODEL_VOTE_SHARE and ratio >= MODEL_RATIO:
            example = paths[int(np.argmax(strongly.any(axis=1)))]
            raise KeypointsFileError(
                f"{example}: keypoints declared {model} look like {other}: read as {other}, the skeletons "
                f"of {share:.0%} of the folder's {n} people are shorter (median {ratio:.2f}x) than read as "
                f"{model}, whose bones join far-apart points; both models have "
                f"{len(KEYPOINT_MODELS[model])} keypoints, so declare the model the files were made with "
                f"({other} likely)")
