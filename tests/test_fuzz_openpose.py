"""OpenPose-family JSON fuzzed (issue 37), for each keypoint model: damaged files through
`read_keypoints_json` in a forked child (tests/fuzz_util.py), and wrong values put in place of a number
(NaN, infinity, a string, a boolean, null, a confidence of 7 or -1). Allowed: a KeypointsFileError naming
the file, or the undamaged people. Silent changes (silent_wrong) only where JSON cannot tell:
the damaged text still parses to the same structure, only numbers changed, and they pass the checks (a
plausible digit changed); a key damaged out of a person warns."""

import json

import numpy as np
import pytest
from fuzz_util import damaged, record

from pingpong.io.openpose_json import KEYPOINT_MODELS

SUMMARY = "test_fuzz_openpose:people_summary"
EXAMPLES = 150  # random damages per model: all four run in a few seconds
WRONG_VALUES = ["NaN", "Infinity", "-Infinity", '"0.5"', "true", "null", "7", "-1", "[]", "{}"]


def people_summary(path, model: str) -> list:
    from pingpong.io.openpose_json import read_keypoints_json

    return read_keypoints_json(path, model).round(6).tolist()


def openpose_file(model: str, rng) -> str:
    """Two people of the model, as OpenPose writes them (its keys beside pose_keypoints_2d)."""
    people = []
    for _ in range(2):
        xy = rng.uniform(0, 1000, (len(KEYPOINT_MODELS[model]), 2)).round(3)
        conf = rng.uniform(0.05, 0.99, (len(xy), 1)).round(6)
        conf[rng.random(len(xy)) < 0.2] = 0.0
        keypoints = np.where(conf > 0, np.hstack([xy, conf]), 0.0)
        people.append({"person_id": [-1], "pose_keypoints_2d": keypoints.ravel().tolist(),
                       "face_keypoints_2d": [], "hand_left_keypoints_2d": []})
    return json.dumps({"version": 1.3, "people": people})


def shape(value):
    """The JSON structure with every number replaced by 0 (booleans are not numbers)."""
    if isinstance(value, dict):
        return {k: shape(v) for k, v in value.items()}
    if isinstance(value, list):
        return [shape(v) for v in value]
    return 0 if type(value) in (int, float) else value


def only_numbers_changed(original: str, text: bytes) -> bool:
    try:
        return shape(json.loads(text)) == shape(json.loads(original))
    except (ValueError, UnicodeDecodeError, RecursionError):
        return False


@pytest.mark.parametrize("model", sorted(KEYPOINT_MODELS))
def test_fuzz_openpose_json(reader, tmp_path, model):
    rng = np.random.default_rng(37)
    original = openpose_file(model, rng)
    path = tmp_path / "cam0_000000000007_keypoints.json"
    path.write_text(original)
    expected = reader.call(SUMMARY, path, model).value
    assert expected is not None and len(expected) == 2
    outcomes, lies = [], []
    values = [v.encode() for v in WRONG_VALUES]
    for k in range(EXAMPLES + len(values)):
        if k < EXAMPLES:
            _, data = damaged(original.encode(), rng)
        else:  # a wrong value in place of one of the first person's keypoint numbers
            head, tail = original.split('"pose_keypoints_2d": [', 1)
            numbers = tail.split(",")
            numbers[(k * 7) % 20] = values[k - EXAMPLES].decode()
            data = (head + '"pose_keypoints_2d": [' + ",".join(numbers)).encode()
        path.write_bytes(data)
        outcome = reader.call(SUMMARY, path, model).outcome(path, expected)
        if outcome == "silent_wrong" and not only_numbers_changed(original, data):
            lies.append(data)  # silent beyond a plausible number changed: never allowed
        outcomes.append(outcome)
    counts = record(f"openpose {model}", outcomes)
    assert counts["crash"] == counts["hang"] == counts["unclear"] == 0 and not lies, (counts, lies[:2])
    assert counts["clean_error"] > EXAMPLES // 2, counts  # most damage breaks the JSON or a check
