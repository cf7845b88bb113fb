"""The sync check: cameras that share a clock pass with their table; every disagreement is an error
naming the camera; drops alone are warnings."""

import logging

import numpy as np
import pytest

from pingpong.perception.sync import CameraSyncError, camera_sync_row, check_sync

FRAME_NS = 10_000_000
START = 1_700_000_000_000_000_000
HEADER = r"session s02: the cameras do not share a clock[\s\S]*"


def clock(n=500, start=START, period=FRAME_NS) -> np.ndarray:
    return start + period * np.arange(n, dtype=np.int64)


def test_cameras_on_one_clock_pass_with_their_table():
    table = check_sync({"cam0": clock(), "cam1": clock(), "cam2": clock()}, "s00")
    assert list(table["camera"]) == ["cam0", "cam1", "cam2"]
    assert (table["frames"] == 500).all() and np.allclose(table["rate_hz"], 100.0)
    assert (table["first_ns"] == START).all() and (table["dropped_frames"] == 0).all()


def test_drops_are_counted_and_warned_about(caplog):
    times = np.delete(clock(), [100, 101, 102, 300])
    with caplog.at_level(logging.WARNING):
        table = check_sync({"cam0": times, "cam1": times}, "s01")
    assert table["dropped_frames"].tolist() == [4, 4]
    assert "session s01: cam1: 4 dropped frame(s)" in caplog.text


@pytest.mark.parametrize(("other", "message"), [
    (clock(period=FRAME_NS * 100 // 101), r"cam1: 101.00 Hz, cam0 100.00 Hz"),
    (clock(start=START + 3 * FRAME_NS), r"cam1: first frame \+30.0 ms from cam0's"),
    (clock(n=480), r"cam1: 480 frames, cam0 500"),
    (np.concatenate([clock(250), clock(250, START + 251 * FRAME_NS)]), r"cam1: frame 250 at \d+ ns, cam0's"),
    (clock()[::-1].copy(), r"cam1: 499 frame time\(s\) not after the one before"),
    (clock(n=1), r"cam1: 1 frame\(s\); a stream needs at least 2"),
])
def test_every_disagreement_names_the_camera(other, message):
    with pytest.raises(CameraSyncError, match=HEADER + message):
        check_sync({"cam0": clock(), "cam1": other, "cam2": clock()}, "s02")


def test_an_empty_stream_is_a_row_without_a_rate():
    row = camera_sync_row("cam3", np.zeros(0, np.int64))
    assert row["frames"] == 0 and np.isnan(row["rate_hz"]) and row["first_ns"] == -1
