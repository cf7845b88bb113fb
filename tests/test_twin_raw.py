"""The twin's raw/ opens with the public tools as a real lab's would: mcap + protobuf decoder,
OpenCV for every JPEG and PNG, OpenPose's JSON layout; timestamps monotonic at the stated rates."""

import json

import cv2
import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory


@pytest.fixture(scope="module")
def raw(tiny_run):
    return tiny_run / "raw"


def _messages(path):
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        yield from reader.iter_decoded_messages()


def test_camera_streams_are_foxglove_jpeg_at_100_hz(raw):
    for cam in ("cam0", "cam1"):
        times, schemas, topics = [], set(), set()
        for schema, channel, message, decoded in _messages(raw / f"sessions/s00/{cam}.mcap"):
            schemas.add(schema.name)
            topics.add(channel.topic)
            assert decoded.format == "jpeg" and decoded.frame_id == cam
            assert decoded.timestamp.ToNanoseconds() == message.log_time
            image = cv2.imdecode(np.frombuffer(decoded.data, np.uint8), cv2.IMREAD_COLOR)
            assert image is not None and image.shape == (360, 480, 3)
            times.append(message.log_time)
        assert schemas == {"foxglove.CompressedImage"} and len(topics) == 1
        assert len(times) > 500 and np.all(np.diff(times) == 10_000_000)


def test_optitrack_stream_has_paddles_above_120_hz_and_table_markers(raw):
    times = {}
    for schema, channel, message, decoded in _messages(raw / "sessions/s00/optitrack.mcap"):
        assert schema.name == "foxglove.PoseInFrame" and decoded.frame_id == "optitrack_world"
        times.setdefault(channel.topic, []).append(message.log_time)
    paddles = [t for t in times if "paddle" in t]
    markers = [t for t in times if "table_marker" in t]
    assert len(paddles) == 2 and len(markers) == 4
    for topic in paddles:
        dt = np.diff(times[topic])
        assert np.all(dt > 0)
        assert 1e9 / np.median(dt) >= 120  # dropouts are gaps, never duplicates


def test_openpose_json_is_openposes_own_format(raw):
    files = sorted((raw / "sessions/s00/openpose/cam0").glob("*_keypoints.json"))
    assert files and files[0].name == "s00_cam0_000000000000_keypoints.json"
    people_seen = 0
    for path in files[::50]:
        frame = json.loads(path.read_text())
        assert frame["version"] == 1.3
        for person in frame["people"]:
            assert len(person["pose_keypoints_2d"]) == 75 and person["person_id"] == [-1]
            people_seen += 1
    assert people_seen > 0


def test_calibration_captures_decode(raw):
    for cam in ("cam0", "cam1"):
        folder = raw / "calibration" / cam
        for path in [*sorted(folder.glob("intrinsics_*.png")), folder / "table.png"]:
            assert cv2.imread(str(path)).shape == (360, 480, 3)
