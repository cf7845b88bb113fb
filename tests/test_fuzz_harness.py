"""The fuzz harness itself: each outcome is told apart, and a crash or hang costs only the child."""

import numpy as np
import pytest
from fuzz_util import IsolatedReader, damaged, tally


@pytest.fixture(scope="module")
def reader():
    isolated = IsolatedReader(timeout_s=2)
    yield isolated
    isolated.close()


def test_returned_raised_crashed_and_hung_are_told_apart(reader, tmp_path):
    path = tmp_path / "input.json"
    path.write_text("{}")
    assert reader.call("json:loads", "[1, 2]").outcome(path, [1, 2]) == "unaffected"
    assert reader.call("json:loads", "[1, 3]").outcome(path, [1, 2]) == "silent_wrong"
    assert reader.call("json:loads", "[1").outcome(path, None) == "unclear"  # a library's own error
    openpose = reader.call("pingpong.io.openpose_json:read_keypoints_json", path)
    assert openpose.outcome(path, None) == "clean_error"
    assert reader.call("os:abort").kind == "crash"
    assert reader.call("time:sleep", 5).kind == "hang"
    assert reader.call("json:loads", "7").value == 7  # a fresh child after each


def test_damage_kinds(tmp_path):
    rng = np.random.default_rng(0)
    data = bytes(range(200))
    kinds = {damaged(data, rng)[0] for _ in range(100)}
    assert kinds == {"truncate", "flip", "insert", "delete", "empty"}
    kind, flipped = damaged(data, rng, kinds=("flip",))
    assert len(flipped) == len(data) and sum(a != b for a, b in zip(flipped, data, strict=True)) == 1
    assert tally(["crash", "unaffected", "unaffected"]) == {
        "examples": 3, "clean_error": 0, "warning": 0, "unaffected": 2, "silent_wrong": 0, "unclear": 0,
        "crash": 1, "hang": 0}
