"""MCAP camera and OptiTrack streams: plain-reader compatibility, round trips, damage, atomicity."""


import cv2
import numpy as np
import pytest
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
from mcap.reader import SeekingReader, make_reader
from mcap.writer import IndexType
from mcap.writer import Writer as McapWriter
from mcap_protobuf.decoder import DecoderFactory
from mcap_protobuf.schema import build_file_descriptor_set
from scipy.spatial.transform import Rotation

from pingpong.common.patterns import TABLE_MARKERS
from pingpong.frames import FRAME_NS
from pingpong.io.mcap_io import (
    CameraStreamWriter,
    McapDamagedError,
    OptitrackWriter,
    _indexed_times,
    read_camera_stream,
    read_camera_times,
    read_optitrack,
)
from pingpong.twin.optitrack_sim import table_to_optitrack, write_optitrack_session

T0 = 1_700_000_000_000_000_000  # an epoch in ns


def jpeg(i: int) -> bytes:
    image = np.full((24, 32, 3), (i * 7) % 256, np.uint8)
    return cv2.imencode(".jpg", image)[1].tobytes()


@pytest.fixture
def camera_file(tmp_path):
    path = tmp_path / "cam2.mcap"
    with CameraStreamWriter(path, 2, "cam2") as writer:
        for i in range(300):
            writer.add(T0 + i * FRAME_NS, jpeg(i) + bytes(2000))  # padding spreads frames over chunks
    return path


def test_plain_mcap_reader_sees_foxglove_compressed_images(camera_file):
    with open(camera_file, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        times = []
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            assert schema.name == "foxglove.CompressedImage" and channel.message_encoding == "protobuf"
            assert channel.topic == "/cam2/image"
            assert decoded.frame_id == "cam2" and decoded.format == "jpeg"
            assert decoded.timestamp.ToNanoseconds() == message.log_time
            assert cv2.imdecode(np.frombuffer(decoded.data, np.uint8), cv2.IMREAD_COLOR) is not None
            times.append(message.log_time)
    assert len(times) == 300 and (np.diff(times) == FRAME_NS).all()  # 100 Hz, monotonic


def test_camera_round_trip(camera_file):
    frames = list(read_camera_stream(camera_file))
    assert [t for t, _ in frames] == [T0 + i * FRAME_NS for i in range(300)]
    assert all(data == jpeg(i) + bytes(2000) for i, (_, data) in enumerate(frames))


@pytest.mark.parametrize("fraction", [0.0005, 0.1, 0.37, 0.5, 0.93, 0.999])
def test_truncated_file_reads_up_to_the_damage(camera_file, tmp_path, fraction):
    data = camera_file.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:int(len(data) * fraction)])
    with pytest.warns(UserWarning, match="cut.mcap.*truncated or corrupt after log_time"):
        frames = list(read_camera_stream(cut))
    expected = [T0 + i * FRAME_NS for i in range(len(frames))]
    assert [t for t, _ in frames] == expected  # a clean prefix
    assert all(d == jpeg(i) + bytes(2000) for i, (_, d) in enumerate(frames))
    with pytest.raises(McapDamagedError, match=r"cut\.mcap: truncated or corrupt after log_time"):
        list(read_camera_stream(cut, strict=True))


def test_corrupt_bytes_are_caught_by_crc(camera_file, tmp_path):
    data = bytearray(camera_file.read_bytes())
    data[len(data) // 2] ^= 0xFF
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(data))
    with pytest.raises(McapDamagedError, match="bad.mcap"):
        list(read_camera_stream(bad, strict=True))


def test_an_exception_leaves_no_file(tmp_path):
    path = tmp_path / "cam0.mcap"
    with pytest.raises(RuntimeError), CameraStreamWriter(path, 0, "cam0") as writer:
        writer.add(T0, jpeg(0))
        raise RuntimeError("killed")
    assert list(tmp_path.iterdir()) == []


def test_frame_times_must_increase(tmp_path):
    with pytest.raises(ValueError, match="does not follow"), \
            CameraStreamWriter(tmp_path / "c.mcap", 0, "cam0") as w:
        w.add(T0, jpeg(0))
        w.add(T0, jpeg(1))
    assert not (tmp_path / "c.mcap").exists()


def kabsch(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """R, t minimising |R a + t - b|."""
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    u, _, vt = np.linalg.svd((a - ca).T @ (b - cb))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    R = vt.T @ np.diag([1, 1, d]) @ u.T
    return R, cb - R @ ca


def test_optitrack_session_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    R, t = table_to_optitrack(rng)
    np.testing.assert_allclose(R @ [0, 0, 1.0], [0, 1.0, 0], atol=1e-12)  # table up is OptiTrack's y
    n = 240 * 4
    times = T0 + np.arange(n) * (1_000_000_000 // 240)
    steps = np.arange(n)
    positions = np.column_stack([np.sin(steps / 50), np.full(n, 1.8), 0.2 + 0.01 * steps / n])
    rotations = Rotation.from_rotvec(np.outer(np.arange(n) / n, [0.3, 0.5, 0.1])).as_matrix()
    path = tmp_path / "optitrack.mcap"
    write_optitrack_session(path, times, {"A": (positions, rotations)}, (R, t), rng, clock_offset_ns=1234)

    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, _, decoded in reader.iter_decoded_messages():
            assert schema.name == "foxglove.PoseInFrame" and decoded.frame_id == "optitrack_world"
            assert channel.topic.startswith("/optitrack/")
    bodies = read_optitrack(path)
    assert set(bodies) == {"paddle_A"} | {f"table_marker_{i}" for i in range(4)}
    paddle = bodies["paddle_A"]
    assert list(paddle.columns) == ["time_ns", "x", "y", "z", "qx", "qy", "qz", "qw"]
    assert 0.9 * n < len(paddle) <= n and paddle.time_ns.is_monotonic_increasing
    index = ((paddle.time_ns.to_numpy() - 1234 - T0) // (1_000_000_000 // 240)).astype(int)
    expected = positions[index] @ R.T + t
    assert np.abs(paddle[["x", "y", "z"]].to_numpy() - expected).max() < 0.002  # 0.3 mm noise
    rot_err = (Rotation.from_quat(paddle[["qx", "qy", "qz", "qw"]].to_numpy()).inv()
               * Rotation.from_matrix(R @ rotations[index])).magnitude()
    assert np.degrees(rot_err).max() < 0.6
    # the table markers give back the table-to-OptiTrack transform (Kabsch)
    means = np.array([bodies[f"table_marker_{i}"][["x", "y", "z"]].mean().to_numpy() for i in range(4)])
    R_est, t_est = kabsch(TABLE_MARKERS, means)
    assert np.abs(R_est - R).max() < 1e-3 and np.abs(t_est - t).max() < 5e-4


@pytest.mark.parametrize("index_types", [IndexType.ALL, IndexType.NONE])
def test_camera_times_from_the_index_are_the_streamed_times(tmp_path, index_types):
    """Two interleaved cameras in small chunks: each topic's times, in file order, come from the message
    indexes where the file has them (no frame read) and from reading it through where it has none."""
    path = tmp_path / "two.mcap"
    with open(path, "wb") as f:
        writer = McapWriter(f, chunk_size=3000, index_types=index_types)
        writer.start()
        schema = writer.register_schema("foxglove.CompressedImage", "protobuf",
                                        build_file_descriptor_set(CompressedImage).SerializeToString())
        channels = {topic: writer.register_channel(topic, "protobuf", schema) for topic in ("/a", "/b")}
        expected = {"/a": [], "/b": []}
        for i in range(120):
            topic, t = ("/a", "/b")[i % 3 == 0], T0 + i * FRAME_NS + (i % 5) * 1000
            message = CompressedImage(frame_id=topic, data=jpeg(i) + bytes(500 * (i % 4)), format="jpeg")
            writer.add_message(channels[topic], log_time=t, data=message.SerializeToString(), publish_time=t)
            expected[topic].append(t)
        writer.finish()
    assert (_indexed_times(path, "foxglove.CompressedImage", "/a") is None) == (index_types == IndexType.NONE)
    for topic, times in expected.items():
        assert read_camera_times(path, topic=topic).tolist() == times
        streamed = [t for t, _ in read_camera_stream(path, topic=topic)]
        assert streamed == times


def first_index_entry(path) -> int:
    """The file offset of the first entry (log_time, then offset) of the first chunk's message index."""
    with open(path, "rb") as f:
        chunk = SeekingReader(f).get_summary().chunk_indexes[0]
    [start] = chunk.message_index_offsets.values()
    return start + 1 + 8 + 2 + 4  # opcode, record length, channel id, length of the entries


def test_a_flipped_bit_in_the_message_index_is_read_past(camera_file):
    """Issue 37: bit 32 of frame 0's log_time in the index (no CRC guards it) moved frame 0 by 4.3 s
    in camera_frame_times; the index is checked against the message it points to and read past."""
    data = bytearray(camera_file.read_bytes())
    data[first_index_entry(camera_file) + 4] ^= 1  # bit 32 of the first log_time
    camera_file.write_bytes(bytes(data))
    with pytest.warns(UserWarning, match=r"cam2\.mcap: its message index disagrees with the file .*log_time "
                                         rf"{T0 ^ 2**32} ns.* read from the messages themselves"):
        times = read_camera_times(camera_file)
    assert times.tolist() == [T0 + i * FRAME_NS for i in range(300)]


def test_a_message_index_of_impossible_length_is_read_past(camera_file):
    """Issue 37: the mcap library's RecordLengthLimitExceeded from parsing a damaged index escaped
    unnamed; now the index is read past with a warning naming the file."""
    data = bytearray(camera_file.read_bytes())
    data[first_index_entry(camera_file) - 14 + 7] = 0xFF  # the top byte of the index record's length
    camera_file.write_bytes(bytes(data))
    with pytest.warns(UserWarning, match=r"cam2\.mcap: its message index disagrees with the file "
                                         r"\(RecordLengthLimitExceeded"):
        times = read_camera_times(camera_file)
    assert times.tolist() == [T0 + i * FRAME_NS for i in range(300)]


def zero_chunks(path) -> None:
    """Zero every chunk record but its length: a record of opcode 0, which readers skip as unknown."""
    data = bytearray(path.read_bytes())
    with open(path, "rb") as f:
        for chunk in SeekingReader(f).get_summary().chunk_indexes:
            start, end = chunk.chunk_start_offset, chunk.chunk_start_offset + chunk.chunk_length
            data[start] = 0
            data[start + 9:end] = bytes(end - start - 9)
    path.write_bytes(bytes(data))


def test_zeroed_optitrack_records_are_an_error(tmp_path):
    """Issue 37: an OptiTrack file whose records were zeroed gave no bodies and no warning."""
    path = tmp_path / "optitrack.mcap"
    with OptitrackWriter(path) as writer:
        for k in range(50):
            writer.add("paddle_A", T0 + k * FRAME_NS, np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
    zero_chunks(path)
    with pytest.warns(UserWarning, match=r"optitrack\.mcap: /optitrack/paddle_A: 0 of the 50 messages its "
                                         r"statistics count"), \
            pytest.raises(McapDamagedError, match=r"optitrack\.mcap: no rigid-body poses"):
        read_optitrack(path)


def test_implausible_poses_are_dropped_with_a_warning(tmp_path):
    path = tmp_path / "optitrack.mcap"
    with OptitrackWriter(path) as writer:
        for k in range(5):
            quaternion = [0.0, 0.0, 0.0, 2.0 if k == 3 else 1.0]
            writer.add("paddle_A", T0 + k * FRAME_NS, [float("nan") if k == 1 else 0.0, 0, 0], quaternion)
    with pytest.warns(UserWarning, match=rf"optitrack\.mcap: 2 poses of paddle_A dropped, the first at "
                                         rf"{T0 + FRAME_NS} ns .*expected finite values and a unit "
                                         "quaternion"):
        poses = read_optitrack(path)["paddle_A"]
    assert poses["time_ns"].tolist() == [T0, T0 + 2 * FRAME_NS, T0 + 4 * FRAME_NS]


def test_a_zeroed_chunk_of_frames_warns(camera_file):
    zero_chunks(camera_file)
    with pytest.warns(UserWarning, match=r"cam2\.mcap: /cam2/image: 0 of the 300 messages its statistics "
                                         r"count; expected foxglove\.CompressedImage frames"):
        assert list(read_camera_stream(camera_file)) == []
    with pytest.raises(McapDamagedError, match=r"cam2\.mcap: /cam2/image: 0 of the 300 messages"):
        list(read_camera_stream(camera_file, strict=True))


# Issue 48: a held-out fuzz run's findings; each now an McapDamagedError naming the file and the message


@pytest.mark.parametrize("read", [read_camera_times, lambda path: list(read_camera_stream(path))])
def test_a_log_time_beyond_int64_is_named(tmp_path, read):
    """MCAP log_times are uint64: 2**63 became an OverflowError naming no file (the index's times) or
    wrapped round to a negative time (the streamed ones)."""
    path = tmp_path / "cam2.mcap"
    with CameraStreamWriter(path, 2, "cam2") as writer:
        for i in range(4):
            writer.add(2**63 - 2 + i, jpeg(i))
    with pytest.raises(McapDamagedError, match=rf"cam2\.mcap: message 2( on /cam2/image)?: log_time {2**63} "
                                               r"does not fit int64; expected int64 ns"):
        read(path)


def test_an_optitrack_log_time_beyond_int64_is_named(tmp_path):
    path = tmp_path / "optitrack.mcap"
    with OptitrackWriter(path) as writer:
        for k in range(3):
            writer.add("paddle_A", 2**63 - 1 + k, np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
    with pytest.raises(McapDamagedError, match=rf"optitrack\.mcap: message 1 on /optitrack/paddle_A: "
                                               rf"log_time {2**63} does not fit int64"):
        read_optitrack(path)


def test_two_channels_of_one_rigid_body_are_an_error(tmp_path):
    """Two channels on /optitrack/paddle_A interleaved their poses into one body without a word."""
    path = tmp_path / "optitrack.mcap"
    with open(path, "wb") as f:
        writer = McapWriter(f)
        writer.start()
        schema = writer.register_schema("foxglove.PoseInFrame", "protobuf",
                                        build_file_descriptor_set(PoseInFrame).SerializeToString())
        channels = [writer.register_channel(topic, "protobuf", schema)
                    for topic in ("/optitrack/paddle_A", "/optitrack/paddle_B", "/optitrack/paddle_A")]
        pose = PoseInFrame(frame_id="optitrack_world")
        pose.pose.orientation.w = 1.0
        for k in range(6):
            writer.add_message(channels[k % 3], log_time=T0 + k, data=pose.SerializeToString(),
                               publish_time=T0 + k)
        writer.finish()
    with pytest.raises(McapDamagedError, match=rf"optitrack\.mcap: two rigid-body channels named 'paddle_A' "
                                               rf"\(channel {channels[0]} and channel {channels[2]}\)"):
        read_optitrack(path)
