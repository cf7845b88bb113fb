"""OpenPose's own per-frame JSON (--write_json, BODY_25), written and read as OpenPose does.

One file per frame `{basename}_{frame:012d}_keypoints.json` holding
{"version":1.3,"people":[{"person_id":[-1],"pose_keypoints_2d":[x,y,c]*25,"face_keypoints_2d":[],
"hand_left_keypoints_2d":[],"hand_right_keypoints_2d":[],"pose_keypoints_3d":[],"face_keypoints_3d":[],
"hand_left_keypoints_3d":[],"hand_right_keypoints_3d":[]}]}, compact, pixels of the source image;
an undetected joint is 0,0,0.
"""

import json
import os
import re
from pathlib import Path

import numpy as np

from pingpong.common.atomic import write_text_atomic

N_JOINTS = 25
EMPTY_FIELDS = ("face_keypoints_2d", "hand_left_keypoints_2d", "hand_right_keypoints_2d", "pose_keypoints_3d",
                "face_keypoints_3d", "hand_left_keypoints_3d", "hand_right_keypoints_3d")
FILE_PATTERN = re.compile(r"_(\d{12})_keypoints\.json$")


def keypoints_filename(basename: str, frame: int) -> str:
    return f"{basename}_{frame:012d}_keypoints.json"


def _number(value: float) -> str:
    """OpenPose prints floats with 6 significant digits and integral zeros as 0."""
    return "0" if value == 0 else f"{value:.6g}"


def format_keypoints_json(people: np.ndarray) -> str:
    """The JSON text of one frame's people (P, 25, 3) [x, y, confidence]."""
    persons = []
    for person in np.asarray(people, float).reshape(-1, N_JOINTS, 3):
        pose = ",".join(_number(v) for v in person.ravel())
        empty = ",".join(f'"{field}":[]' for field in EMPTY_FIELDS)
        persons.append(f'{{"person_id":[-1],"pose_keypoints_2d":[{pose}],{empty}}}')
    return '{"version":1.3,"people":[' + ",".join(persons) + "]}"


def write_keypoints_json(folder: str | os.PathLike, basename: str, frame: int, people: np.ndarray) -> Path:
    """Write one frame's file (atomically) and return its path."""
    path = Path(folder) / keypoints_filename(basename, frame)
    write_text_atomic(path, format_keypoints_json(people))
    return path


def read_keypoints_json(path: str | os.PathLike) -> np.ndarray:
    """People (P, 25, 3) of one OpenPose JSON file; a clear error names the file on bad content."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
        people = [np.asarray(person["pose_keypoints_2d"], float) for person in doc["people"]]
    except (ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{path}: not an OpenPose keypoints JSON ({type(exc).__name__}: {exc}); expected "
                         '{"version":..,"people":[{"pose_keypoints_2d":[x,y,c]*25,..}]}') from exc
    for i, pose in enumerate(people):
        if pose.size != 3 * N_JOINTS:
            raise ValueError(f"{path}: person {i} has {pose.size} pose values, "
                             f"expected {3 * N_JOINTS} (BODY_25)")
    return np.reshape(people, (-1, N_JOINTS, 3))


def read_keypoints_folder(folder: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Frame numbers (F,) and keypoints (F, P_max, 25, 3) of every *_keypoints.json in a folder.

    Frames are sorted by the 12-digit frame number in the names; people are padded with zeros
    (confidence 0 = absent) to the largest count in any frame, in file order.
    """
    entries = sorted((int(m.group(1)), p) for p in Path(folder).iterdir()
                     if (m := FILE_PATTERN.search(p.name)))
    frames = np.array([frame for frame, _ in entries], np.int64)
    per_frame = [read_keypoints_json(path) for _, path in entries]
    most = max((len(people) for people in per_frame), default=0)
    out = np.zeros((len(entries), most, N_JOINTS, 3))
    for i, people in enumerate(per_frame):
        out[i, :len(people)] = people
    return frames, out
