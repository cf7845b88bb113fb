"""OpenPose-family per-frame JSON (--write_json): read in any of four keypoint models, written as BODY_25.

One file per frame, {"version":1.3,"people":[{"person_id":[-1],"pose_keypoints_2d":[x,y,c]*K,
"face_keypoints_2d":[],"hand_left_keypoints_2d":[],"hand_right_keypoints_2d":[],"pose_keypoints_3d":[],
"face_keypoints_3d":[],"hand_left_keypoints_3d":[],"hand_right_keypoints_3d":[]}]}, compact, pixels of
the source image; an undetected joint is 0,0,0. K is the model's keypoint count, which the file does not
name: the caller declares the model (KEYPOINT_MODELS) and the reader maps its joints by name into the
BODY_25 layout (`to_body25`). Files are named by one of LAYOUTS (or a caller's regex); the writer writes
BODY_25 in OpenPose's own layout, as the digital twin needs.
"""

import json
import os
import re
from pathlib import Path

import numpy as np

from pingpong.common.atomic import write_text_atomic
from pingpong.frames import BODY25

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


def to_body25(keypoints: np.ndarray, model: str) -> np.ndarray:
    """(..., 25, 3) BODY_25 layout of keypoints (..., K, 3) in the model's order, mapped by joint name;
    a BODY_25 joint the model lacks is 0, 0, 0 (absent) unless derived (MIDPOINTS)."""
    names = [BODY25_NAME.get(name, name) for name in model_keypoint_names(model)]
    keypoints = np.asarray(keypoints, float)
    out = np.zeros((*keypoints.shape[:-2], N_JOINTS, 3))
    shared = [(BODY25.index(name), k) for k, name in enumerate(names) if name in BODY25]
    out[..., [j for j, _ in shared], :] = keypoints[..., [k for _, k in shared], :]
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


def read_keypoints_json(path: str | os.PathLike, model: str = "BODY_25") -> np.ndarray:
    """People (P, 25, 3) in BODY_25 layout of one file of the declared model; errors name the file."""
    path = Path(path)
    names = model_keypoint_names(model)
    try:
        doc = json.loads(path.read_text())
        people = [np.asarray(person["pose_keypoints_2d"], float) for person in doc["people"]]
    except (ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{path}: not an OpenPose keypoints JSON ({type(exc).__name__}: {exc}); expected "
                         '{"version":..,"people":[{"pose_keypoints_2d":[x,y,c]*K,..}]}') from exc
    for i, pose in enumerate(people):
        if pose.size != 3 * len(names):
            raise ValueError(f"{path}: person {i} has {pose.size} pose_keypoints_2d values, expected "
                             f"{3 * len(names)} ({len(names)} keypoints x 3) for {model}"
                             f"{_count_hint(pose.size, model)}")
    return to_body25(np.reshape(people, (-1, len(names), 3)), model)


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
        raise ValueError(f"{folder}: no per-frame keypoints files; expected names {_describe(patterns)}; "
                         f"{seen}")
    if len(used) > 1:
        examples = ", ".join(f"{layout}: e.g. {found[layout][0]!r}" for layout in used)
        raise ValueError(f"{folder}: per-frame files of {len(used)} layouts mixed ({examples}); "
                         "keep one layout per folder or declare the pattern")
    return patterns[used[0]], found[used[0]]


def _frame_number(path: Path, pattern: re.Pattern) -> int:
    number = pattern.fullmatch(path.name).group(1)
    if number is None or not number.isdigit():
        raise ValueError(f"{path}: the group of file pattern {pattern.pattern!r} holds {number!r}, "
                         "expected the frame number (digits)")
    return int(number)


def list_frame_files(folder: str | os.PathLike,
                     pattern: str | re.Pattern | None = None) -> list[tuple[int, Path]]:
    """(frame, path) of a folder's per-frame files in frame order (the number in the name, numerically).

    Files of other names are ignored; none matching, two layouts mixed, two files of one frame or
    a frame missing between the first and the last are errors.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise ValueError(f"{folder}: not a folder (expected one of per-frame keypoints JSON files)")
    matched, names = _matching_names(folder, layout_patterns(pattern))
    entries = sorted((_frame_number(folder / name, matched), folder / name) for name in names)
    frames = np.array([frame for frame, _ in entries])
    steps = np.diff(frames)
    if (steps == 0).any():
        frame = frames[np.argmax(steps == 0)]
        same = ", ".join(path.name for f, path in entries if f == frame)
        raise ValueError(f"{folder}: frame {frame} has more than one file ({same}); expected one per frame")
    if (steps > 1).any():
        k = np.argmax(steps > 1)
        raise ValueError(f"{folder}: frame {frames[k] + 1} missing (files of frames {frames[k]} then "
                         f"{frames[k + 1]}); expected every frame from {frames[0]} to {frames[-1]}")
    return entries


def read_keypoints_folder(folder: str | os.PathLike, model: str = "BODY_25",
                          pattern: str | re.Pattern | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Frame numbers (F,) and keypoints (F, P_max, 25, 3), BODY_25 layout, of a folder's per-frame files.

    Frames in the order of their numbers (`list_frame_files`); people are padded with zeros
    (confidence 0 = absent) to the largest count in any frame, in file order.
    """
    entries = list_frame_files(folder, pattern)
    frames = np.array([frame for frame, _ in entries], np.int64)
    per_frame = [read_keypoints_json(path, model) for _, path in entries]
    most = max((len(people) for people in per_frame), default=0)
    out = np.zeros((len(entries), most, N_JOINTS, 3))
    for i, people in enumerate(per_frame):
        out[i, :len(people)] = people
    return frames, out
