"""Camera streams fuzzed (issue 37): Foxglove MCAP, ROS 2 CompressedImage and Image bags, MP4/MKV/AVI.

Each damaged file goes through both readers of a stream (`camera_frame_times` and every frame of
`open_camera_stream`, decoded) in a forked child (tests/fuzz_util.py). Allowed outcomes: a
CameraStreamError naming the file, a warning naming it, the undamaged result, or a frame the reader marks
bad (decode gives no image and its reason: the detection stage logs it, naming the frame; counted with the
warnings). Silent: only pixels of frames whose times are all right, where JPEG and H.264 pixel data carry
no check (counted apart, `pixels`).
"""

import zlib

import numpy as np
import pytest
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from fuzz_util import damaged, record
from mcap.reader import SeekingReader
from mcap.writer import CompressionType
from mcap_protobuf.writer import Writer as ProtobufWriter
from test_camera_streams import (
    COMPRESSED_MSGDEF,
    TIMES,
    N,
    compressed_messages,
    jpeg,
    raw_bag,
    square_image,
    write_bag,
    write_video,
)

SUMMARY = "test_fuzz_streams:stream_summary"
EXAMPLES = 120  # random damages per format; with the targeted cases all formats run in about a minute


def stream_summary(path, **kwargs) -> dict:
    """What a consumer of the stream sees: the frame times of both readers, each frame's pixels (CRC) or
    that it was marked bad."""
    from pingpong.io.camera_streams import camera_frame_times, open_camera_stream

    times = tuple(camera_frame_times(path, **kwargs).tolist())
    _, frames = open_camera_stream(path, **kwargs)
    decoded = []
    for frame in frames:
        image, reason = frame.decode()
        decoded.append((frame.time_ns, None if image is None else zlib.crc32(image.tobytes()), bool(reason)))
    return {"times": times, "frames": tuple(decoded)}


def classify(result, path, expected) -> str:
    """The harness's outcome; a silent change confined to frames, with every time right, is either a frame
    marked bad (-> warning) or changed pixels (-> silent_wrong, the format cannot tell)."""
    outcome = result.outcome(path, expected)
    if outcome != "silent_wrong":
        return outcome
    value = result.value
    streamed = tuple(t for t, *_ in value["frames"])
    if value["times"] != expected["times"] or streamed != expected["times"]:
        return "lie"  # wrong times or frames without a word: never allowed
    changed = [(a, b) for a, b in zip(value["frames"], expected["frames"], strict=True) if a != b]
    return "warning" if all(a[2] or a[1] is None for a, _ in changed) else "silent_wrong"


def foxglove_chunked(path, compression=CompressionType.NONE):
    """A Foxglove camera file of small uncompressed chunks (a message index after each), as the twin's
    long recordings have."""
    with open(path, "wb") as f:
        writer = ProtobufWriter(f, chunk_size=3000, compression=compression)
        for i, t in enumerate(TIMES):
            message = CompressedImage(frame_id="cam0", data=jpeg(square_image(i)), format="jpeg")
            message.timestamp.FromNanoseconds(t)
            writer.write_message("/cam0/image", message, log_time=t, publish_time=t)
        writer.finish()
    return path


def index_ranges(path) -> list[tuple[int, int]]:
    """The byte ranges of the message indexes that follow the file's chunks."""
    with open(path, "rb") as f:
        summary = SeekingReader(f).get_summary()
    return [(c.chunk_start_offset + c.chunk_length,
             c.chunk_start_offset + c.chunk_length + c.message_index_length) for c in summary.chunk_indexes]


FORMATS = {
    "foxglove_mcap": lambda d: foxglove_chunked(d / "cam0.mcap"),
    "ros2_compressed": lambda d: write_bag(d / "bag.mcap", "sensor_msgs/msg/CompressedImage",
                                           COMPRESSED_MSGDEF, {"/cam0/image/compressed":
                                                               compressed_messages("jpeg")}, chunk_size=4096),
    "ros2_raw": lambda d: raw_bag(d / "bag.mcap", chunk_size=4096),
    "mp4": lambda d: write_video(d / "cam0.mp4", "libx264"),
    "mkv": lambda d: write_video(d / "cam0.mkv", "libx264"),
    "avi": lambda d: write_video(d / "cam0.avi", "mpeg4"),
}


def fuzz(reader, original, cases, name: str) -> tuple[dict, list]:
    """Every (kind, bytes) case through the readers; the counts recorded, and the cases that lied."""
    undamaged = reader.call(SUMMARY, original)
    assert undamaged.kind == "returned" and not undamaged.warned, undamaged
    expected = undamaged.value
    assert expected["times"][:1] in ((TIMES[0],), (0,)) and len(expected["frames"]) == N
    outcomes, bad = [], []
    for n, (kind, data) in enumerate(cases):
        path = original.with_name(f"damaged{n}{original.suffix}")
        path.write_bytes(data)
        outcome = classify(reader.call(SUMMARY, path), path, expected)
        outcomes.append(outcome)
        if outcome not in ("clean_error", "warning", "unaffected", "silent_wrong"):
            bad.append((n, kind, outcome, reader.call(SUMMARY, path)))
        path.unlink()
    return record(name, outcomes), bad


@pytest.mark.parametrize("name", list(FORMATS))
def test_fuzz_camera_stream(reader, tmp_path, name):
    original = FORMATS[name](tmp_path)
    data = original.read_bytes()
    rng = np.random.default_rng(37)
    cases = [damaged(data, rng) for _ in range(EXAMPLES)]
    counts, bad = fuzz(reader, original, cases, f"camera {name}")
    assert not bad, bad[:3]
    assert counts["crash"] == counts["hang"] == counts["unclear"] == 0
    if name not in ("mp4", "mkv", "avi"):
        assert counts["silent_wrong"] == 0  # MCAP chunks carry a CRC over the images too


@pytest.mark.parametrize("compression", [CompressionType.NONE, CompressionType.ZSTD])
def test_fuzz_camera_mcap_message_index(reader, tmp_path, compression):
    """Issue 37: a flipped bit in a message index made camera_frame_times give frame 0 4.3 s early while
    the frames said otherwise. Message indexes carry no CRC: each entry is now checked against the message
    it points to, and an index that disagrees is read past, from the messages, with a warning."""
    original = foxglove_chunked(tmp_path / "cam0.mcap", compression)
    data = original.read_bytes()
    ranges = index_ranges(original)
    assert len(ranges) > 3
    rng = np.random.default_rng(42)
    cases = []
    for _ in range(200):
        start, end = ranges[int(rng.integers(len(ranges)))]
        at = int(rng.integers(start, end))
        cases.append(("flip", data[:at] + bytes([data[at] ^ (1 << int(rng.integers(8)))]) + data[at + 1:]))
    counts, bad = fuzz(reader, original, cases,
                       f"camera foxglove_mcap message index ({compression.name.lower()})")
    assert not bad, bad[:3]
    assert counts["silent_wrong"] == 0 and counts["warning"] > 100  # times do not come from pixels
