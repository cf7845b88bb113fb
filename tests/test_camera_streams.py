"""Camera streams in every format labs record, behind one reader: detection, times, decoded images, and a
clear error for each unreadable input. All data is written here, small."""

import logging

import av
import cv2
import numpy as np
import pytest
from mcap.writer import Writer as McapWriter
from mcap_ros2.writer import Writer as Ros2Writer

from pingpong.frames import FRAME_NS
from pingpong.io.camera_streams import CameraStreamError, RawFrame, camera_frame_times, open_camera_stream
from pingpong.io.mcap_io import CameraStreamWriter, OptitrackWriter

T0 = 1_700_000_000_000_000_000  # an epoch in ns
W, H, N = 64, 48, 12
TIMES = [T0 + i * FRAME_NS for i in range(N)]
SEPARATOR = "=" * 80
DEPENDENCIES = (f"{SEPARATOR}\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
                f"{SEPARATOR}\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n")
COMPRESSED_MSGDEF = "std_msgs/Header header\nstring format\nuint8[] data\n" + DEPENDENCIES
IMAGE_MSGDEF = ("std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\n"
                "uint32 step\nuint8[] data\n" + DEPENDENCIES)


def square_image(i: int) -> np.ndarray:
    """BGR: a bright square, 10 px, moving 4 px right per frame on a dark background (distinct channels)."""
    image = np.empty((H, W, 3), np.uint8)
    image[:] = (30, 60, 90)
    image[16:26, 4 * i:4 * i + 10] = (255, 200, 150)
    return image


def square_centre(i: int, reduction: int = 1) -> np.ndarray:
    """The square's centroid (x, y) in pixels of an image at 1/reduction of the full size."""
    return (np.array([4 * i + 4.5, 20.5]) + 0.5) / reduction - 0.5


def centroid(image: np.ndarray) -> np.ndarray:
    ys, xs = np.nonzero(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) > 128)
    return np.array([xs.mean(), ys.mean()])


def jpeg(image: np.ndarray) -> bytes:
    return cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 95])[1].tobytes()


def header(time_ns: int, frame_id: str = "cam0") -> dict:
    return {"stamp": {"sec": time_ns // 1_000_000_000, "nanosec": time_ns % 1_000_000_000},
            "frame_id": frame_id}


def write_bag(path, schema_name: str, msgdef: str, messages_by_topic: dict[str, list[dict]], **writer_args):
    """A ROS 2 bag; log_time = the stamp plus a varying transport delay, so that the two differ."""
    with open(path, "wb") as f, Ros2Writer(f, **writer_args) as writer:
        schema = writer.register_msgdef(schema_name, msgdef)
        for topic, messages in messages_by_topic.items():
            for i, message in enumerate(messages):
                stamp = message["header"]["stamp"]
                log_time = stamp["sec"] * 1_000_000_000 + stamp["nanosec"] + 3_000_000 + 137_000 * (i % 5)
                writer.write_message(topic, schema, message, log_time=log_time)
    return path


def compressed_messages(image_format: str, times=TIMES) -> list[dict]:
    encode = (lambda image: cv2.imencode(".png", image)[1].tobytes()) if image_format == "png" else jpeg
    return [{"header": header(t), "format": image_format, "data": encode(square_image(i))}
            for i, t in enumerate(times)]


RAW_LAYOUTS = {"bgr8": (3, lambda bgr: bgr), "rgb8": (3, lambda bgr: bgr[..., ::-1]),
               "mono8": (1, lambda bgr: cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)[..., None])}


def raw_message(i: int, time_ns: int, encoding: str, padding: int = 7) -> dict:
    """sensor_msgs/msg/Image of square_image(i), each row followed by `padding` bytes of 0xAB."""
    channels, convert = RAW_LAYOUTS.get(encoding, (4, None))
    pixels = convert(square_image(i)) if convert else np.zeros((H, W, channels), np.uint8)
    step = W * channels + padding
    rows = np.full((H, step), 0xAB, np.uint8)
    rows[:, :W * channels] = pixels.reshape(H, W * channels)
    return {"header": header(time_ns), "height": H, "width": W, "encoding": encoding, "is_bigendian": 0,
            "step": step, "data": rows.tobytes()}


def raw_bag(path, encoding: str = "bgr8", times=TIMES, **writer_args):
    messages = [raw_message(i, t, encoding) for i, t in enumerate(times)]
    return write_bag(path, "sensor_msgs/msg/Image", IMAGE_MSGDEF, {"/cam0/image_raw": messages},
                     **writer_args)


def write_video(path, codec: str, rate: int = 100, options: dict | None = None):
    with av.open(str(path), "w", options=options or {}) as container:
        stream = container.add_stream(codec, rate=rate)
        stream.width, stream.height, stream.pix_fmt = W, H, "yuv420p"
        for i in range(N):
            container.mux(stream.encode(av.VideoFrame.from_ndarray(square_image(i), format="bgr24")))
        container.mux(stream.encode())
    return path


def foxglove_file(path):
    with CameraStreamWriter(path, 0, "cam0") as writer:
        for i, t in enumerate(TIMES):
            writer.add(t, jpeg(square_image(i)))
    return path


def read_all(path, **kwargs) -> list[int]:
    """Every frame's time, reading the stream to its end."""
    _, frames = open_camera_stream(path, **kwargs)
    return [frame.time_ns for frame in frames]


READERS = [read_all, camera_frame_times]


def opened(path, caplog, expected_format: str, **kwargs) -> list:
    """The frames of a stream, checking the format it was detected as and that the log names it."""
    with caplog.at_level(logging.INFO, logger="pingpong.io.camera_streams"):
        format_name, frames = open_camera_stream(path, **kwargs)
        frames = list(frames)
    assert format_name == expected_format
    assert f"{path}: camera stream format {expected_format}" in caplog.text
    return frames


def check_squares(frames, tolerance_px: float = 1.0):
    """Lossy frames: the square is where it was drawn, at full and at half size."""
    for i, frame in enumerate(frames):
        image, reason = frame.decode()
        assert reason == "" and image.shape == (H, W, 3) and image.dtype == np.uint8
        assert np.abs(centroid(image) - square_centre(i)).max() < tolerance_px
        half, reason = frame.decode(2)
        assert reason == "" and half.shape == (H // 2, W // 2, 3)
        assert np.abs(centroid(half) - square_centre(i, 2)).max() < tolerance_px


def check_exact(frames, expected_bgr):
    """Lossless frames: exactly what was written, and decode(2) is its INTER_AREA half."""
    for i, frame in enumerate(frames):
        image, reason = frame.decode()
        expected = expected_bgr(i)
        assert reason == "" and np.array_equal(image, expected)
        half, _ = frame.decode(2)
        assert np.array_equal(half, cv2.resize(expected, (W // 2, H // 2), interpolation=cv2.INTER_AREA))


# ---- each format


def test_foxglove_mcap(tmp_path, caplog):
    path = foxglove_file(tmp_path / "cam0.mcap")
    frames = opened(path, caplog, "foxglove_mcap")
    assert [f.time_ns for f in frames] == TIMES
    assert list(camera_frame_times(path)) == TIMES
    check_squares(frames)


@pytest.mark.parametrize("image_format", ["jpeg", "png", "bgr8; jpeg compressed bgr8"])
def test_ros2_compressed(tmp_path, caplog, image_format):
    path = write_bag(tmp_path / "bag.mcap", "sensor_msgs/msg/CompressedImage", COMPRESSED_MSGDEF,
                     {"/cam0/image_raw/compressed": compressed_messages(image_format)})
    frames = opened(path, caplog, "ros2_compressed")
    assert [f.time_ns for f in frames] == TIMES  # the header stamps, not log_time
    assert list(camera_frame_times(path)) == TIMES
    if image_format == "png":
        check_exact(frames, square_image)
    else:
        check_squares(frames)


@pytest.mark.parametrize("encoding", ["bgr8", "rgb8", "mono8"])
def test_ros2_raw_with_row_padding(tmp_path, caplog, encoding):
    path = raw_bag(tmp_path / "bag.mcap", encoding)
    frames = opened(path, caplog, "ros2_raw")
    assert [f.time_ns for f in frames] == TIMES
    assert list(camera_frame_times(path)) == TIMES
    if encoding == "mono8":
        check_exact(frames, lambda i: cv2.cvtColor(cv2.cvtColor(square_image(i), cv2.COLOR_BGR2GRAY),
                                                   cv2.COLOR_GRAY2BGR))
    else:
        check_exact(frames, square_image)


def codec_case(extension: str, codec: str):
    return pytest.param(extension, codec, id=f"{extension}-{codec}",
                        marks=pytest.mark.skipif(codec not in av.codecs_available,
                                                 reason=f"PyAV build without {codec}"))


VIDEOS = [codec_case("mp4", "libx264"), codec_case("mp4", "mpeg4"), codec_case("avi", "mpeg4"),
          codec_case("mkv", "libx264"),
          codec_case("avi", "libx264")]  # B-frames in AVI: the decoded frames' own pts come shuffled


@pytest.mark.parametrize("extension, codec", VIDEOS)
def test_video_with_container_times(tmp_path, caplog, extension, codec):
    path = write_video(tmp_path / f"cam0.{extension}", codec)
    frames = opened(path, caplog, "video", start_ns=T0)
    assert [f.time_ns for f in frames] == TIMES
    assert list(camera_frame_times(path, start_ns=T0)) == TIMES
    assert camera_frame_times(path)[0] == 0  # start_ns defaults to 0
    check_squares(frames)


@pytest.mark.parametrize("extension, codec", VIDEOS[:3])
def test_video_with_timestamp_csv(tmp_path, caplog, extension, codec):
    path = write_video(tmp_path / f"cam0.{extension}", codec)
    times = [T0 + i * FRAME_NS + (i * i * 1234) % 999_983 for i in range(N)]  # irregular: the CSV wins
    csv = tmp_path / "cam0_timestamps.csv"
    csv.write_text("frame,time_ns\n" + "".join(f"{i},{t}\n" for i, t in enumerate(times)))
    frames = opened(path, caplog, "video", timestamps=csv, start_ns=5)
    assert [f.time_ns for f in frames] == times
    assert list(camera_frame_times(path, timestamps=csv)) == times
    check_squares(frames)


def test_a_raw_frame_of_the_wrong_size_does_not_decode():
    frame = RawFrame(T0, bytes(40), width=4, height=4, step=12, encoding="bgr8")
    assert frame.decode() == (None, "40 bytes, expected step 12 x height 4 = 48")
    frame = RawFrame(T0, bytes(40), width=4, height=4, step=10, encoding="bgr8")
    assert frame.decode()[1] == "step 10 bytes, shorter than a row of 4 bgr8 pixels"


def test_topic_chooses_among_image_topics(tmp_path):
    later = [t + 1000 for t in TIMES]
    path = write_bag(tmp_path / "bag.mcap", "sensor_msgs/msg/CompressedImage", COMPRESSED_MSGDEF,
                     {"/cam0/image/compressed": compressed_messages("jpeg"),
                      "/cam1/image/compressed": compressed_messages("jpeg", later)})
    assert read_all(path, topic="/cam1/image/compressed") == later
    assert list(camera_frame_times(path, topic="/cam0/image/compressed")) == TIMES


# ---- bad inputs: each a CameraStreamError naming the file and what was expected


@pytest.mark.parametrize("read", READERS)
def test_empty_file(tmp_path, read):
    path = tmp_path / "cam0.mcap"
    path.write_bytes(b"")
    with pytest.raises(CameraStreamError, match=r"cam0\.mcap: empty file \(0 bytes\); expected a camera"):
        read(path)


@pytest.mark.parametrize("read", READERS)
def test_truncated_bag_reads_up_to_the_damage_or_raises_when_strict(tmp_path, read):
    data = raw_bag(tmp_path / "bag.mcap", chunk_size=4096).read_bytes()  # a chunk per frame
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:len(data) // 2])
    with pytest.warns(UserWarning, match=r"cut\.mcap: truncated or corrupt after log_time"):
        times = list(read(cut))
    assert 0 < len(times) < N and times == TIMES[:len(times)]
    with pytest.raises(CameraStreamError, match=r"cut\.mcap: truncated or corrupt after log_time"):
        read(cut, strict=True)


@pytest.mark.parametrize("read", READERS)
def test_bag_truncated_before_any_channel(tmp_path, read):
    data = raw_bag(tmp_path / "bag.mcap").read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:40])
    with pytest.raises(CameraStreamError, match=r"cut\.mcap: MCAP with no camera image channel "
                                                r"\(no channels\); truncated or corrupt .*; expected one of"):
        read(cut)


@pytest.mark.parametrize("read", READERS)
def test_truncated_video(tmp_path, read):
    data = write_video(tmp_path / "cam0.mp4", "mpeg4").read_bytes()
    cut = tmp_path / "cut.mp4"
    cut.write_bytes(data[:len(data) // 2])
    # the index (moov atom) comes last: FFmpeg either refuses the file or finds no video stream in it
    with pytest.raises(CameraStreamError, match=r"cut\.mp4: .*(does not open as a video|no video stream)"
                                                r".*truncated or corrupt"):
        read(cut)


@pytest.mark.parametrize("read", READERS)
def test_truncated_video_with_its_index_first(tmp_path, read):
    path = write_video(tmp_path / "cam0.mp4", "mpeg4", options={"movflags": "faststart"})
    data = path.read_bytes()
    cut = tmp_path / "cut.mp4"
    cut.write_bytes(data[:int(len(data) * 0.95)])
    with pytest.warns(UserWarning, match=rf"cut\.mp4: \d+ of the {N} frames its header declares: truncated"):
        times = list(read(cut, start_ns=T0))
    assert 0 < len(times) < N and times == TIMES[:len(times)]
    with pytest.raises(CameraStreamError, match=rf"cut\.mp4: \d+ of the {N} frames its header declares"):
        read(cut, strict=True)


@pytest.mark.parametrize("read", READERS)
def test_text_file(tmp_path, read):
    path = tmp_path / "cam0.txt"
    path.write_text("frame,time_ns\n0,1\n")
    with pytest.raises(CameraStreamError, match=r"cam0\.txt: foreign format .*; expected an MCAP file or a "
                                                r"video container \(MP4/MOV, AVI, Matroska/WebM\)"):
        read(path)


@pytest.mark.parametrize("read", READERS)
def test_mcap_without_image_channel_names_its_schemas(tmp_path, read):
    path = tmp_path / "optitrack.mcap"
    with OptitrackWriter(path) as writer:
        writer.add("paddle_A", T0, np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
    with pytest.raises(CameraStreamError, match=r"optitrack\.mcap: MCAP with no camera image channel "
                                                r"\(/optitrack/paddle_A: foxglove\.PoseInFrame "
                                                r"\(protobuf\)\); expected one of "
                                                r"foxglove\.CompressedImage \(protobuf\), "
                                                r"sensor_msgs/msg/CompressedImage \(cdr\)"):
        read(path)


@pytest.mark.parametrize("read", READERS)
def test_two_image_topics_ask_which(tmp_path, read):
    path = write_bag(tmp_path / "bag.mcap", "sensor_msgs/msg/Image", IMAGE_MSGDEF,
                     {"/cam0/image_raw": [raw_message(0, T0, "bgr8")],
                      "/cam1/image_raw": [raw_message(0, T0, "bgr8")]})
    with pytest.raises(CameraStreamError, match=r"bag\.mcap: 2 image topics \(/cam0/image_raw, "
                                                r"/cam1/image_raw\); pass topic= to say which"):
        read(path)
    with pytest.raises(CameraStreamError, match=r"bag\.mcap: no image topic '/cam2/image_raw'; its image "
                                                r"topics: /cam0/image_raw, /cam1/image_raw"):
        read(path, topic="/cam2/image_raw")


@pytest.mark.parametrize("read", READERS)
def test_timestamp_csv_with_a_row_too_few(tmp_path, read):
    path = write_video(tmp_path / "cam0.mp4", "mpeg4")
    csv = tmp_path / "cam0.csv"
    csv.write_text("time_ns\n" + "".join(f"{t}\n" for t in TIMES[:-1]))
    with pytest.raises(CameraStreamError, match=rf"cam0\.csv: {N - 1} timestamp rows, but video .*cam0\.mp4 "
                                                rf"has {N} frames; expected one row per frame"):
        read(path, timestamps=csv)


@pytest.mark.parametrize("text, message", [
    ("t\n1\n", r"columns \['t'\], expected a time_ns column"),
    ("time_ns\n1\n2\nabc\n", r"row 3 has time_ns 'abc', expected an integer \(ns\)"),
    ("frame,time_ns\n0,1\n1,\n", r"row 2 has time_ns nan, expected an integer \(ns\)"),
    ("time_ns\n1\n3\n2\n", r"row 3 has time_ns 2, not after row 2's 3; expected strictly increasing"),
    ("time_ns\n5\n5\n", r"row 2 has time_ns 5, not after row 1's 5; expected strictly increasing"),
    # issue 48: an OverflowError naming no file
    ("time_ns\n5\n99999999999999999999\n", r"row 2: time_ns 99999999999999999999 does not fit int64"),
    ("time_ns\n-9223372036854775809\n5\n", r"row 1: time_ns -9223372036854775809 does not fit int64"),
])
def test_bad_timestamp_csv(tmp_path, text, message):
    path = write_video(tmp_path / "cam0.mp4", "mpeg4")
    csv = tmp_path / "cam0.csv"
    csv.write_text(text)
    with pytest.raises(CameraStreamError, match=r"cam0\.csv: " + message):
        camera_frame_times(path, timestamps=csv)


@pytest.mark.parametrize("read", READERS)
def test_a_stream_of_no_frames(tmp_path, read):
    path = tmp_path / "bag.mcap"
    with open(path, "wb") as f:  # a channel, registered, that no message follows
        writer = McapWriter(f)
        writer.start(profile="ros2")
        schema_id = writer.register_schema("sensor_msgs/msg/Image", "ros2msg", IMAGE_MSGDEF.encode())
        writer.register_channel("/cam0/image_raw", "cdr", schema_id)
        writer.finish()
    with pytest.raises(CameraStreamError, match=r"bag\.mcap: no frames; expected a camera stream of at"):
        read(path)


@pytest.mark.parametrize("encoding", ["bgra8", "16UC1"])
def test_refused_raw_encoding_is_named(tmp_path, encoding):
    path = raw_bag(tmp_path / "bag.mcap", encoding)
    with pytest.raises(CameraStreamError, match=rf"bag\.mcap: frame 0 on /cam0/image_raw has encoding "
                                                rf"'{encoding}'; expected one of bgr8, rgb8, mono8"):
        read_all(path)


def test_refused_compressed_format_is_named(tmp_path):
    path = write_bag(tmp_path / "bag.mcap", "sensor_msgs/msg/CompressedImage", COMPRESSED_MSGDEF,
                     {"/cam0/depth": compressed_messages("16UC1; compressedDepth png")})
    with pytest.raises(CameraStreamError, match=r"bag\.mcap: frame 0 on /cam0/depth has format "
                                                r"'16UC1; compressedDepth png'; expected jpeg or png"):
        read_all(path)


@pytest.mark.parametrize("read", READERS)
def test_stamps_that_do_not_increase(tmp_path, read):
    path = raw_bag(tmp_path / "bag.mcap", times=[T0, T0 + FRAME_NS, T0 + FRAME_NS])
    with pytest.raises(CameraStreamError, match=rf"bag\.mcap: frame 2 at {T0 + FRAME_NS} ns does not "
                                                rf"follow frame 1 at {T0 + FRAME_NS} ns; expected strictly"):
        read(path)


@pytest.mark.parametrize("read", READERS)
def test_video_times_are_refused_for_mcap(tmp_path, read):
    path = foxglove_file(tmp_path / "cam0.mcap")
    with pytest.raises(CameraStreamError, match=r"cam0\.mcap: foxglove_mcap carries its own camera times"):
        read(path, start_ns=T0)


@pytest.mark.parametrize("read", READERS)
def test_video_cut_short_of_its_declared_duration(tmp_path, read):
    """Issue 37: a Matroska file cut to 90 % read as 6 of its 12 frames without a word (Matroska declares
    no frame count, only a duration)."""
    data = write_video(tmp_path / "cam0.mkv", "libx264").read_bytes()
    cut = tmp_path / "cut.mkv"
    cut.write_bytes(data[:int(len(data) * 0.9)])
    with pytest.warns(UserWarning, match=r"cut\.mkv: 6 frames cover 0\.060 s of the 0\.120 s its header "
                                         r"declares \(about 12 frames\): truncated or frames lost"):
        times = list(read(cut, start_ns=T0))
    assert times == TIMES[:6]
    with pytest.raises(CameraStreamError, match=r"cut\.mkv: 6 frames cover 0\.060 s"):
        read(cut, strict=True)


@pytest.mark.parametrize("read", READERS)
def test_a_video_frame_lost_in_the_middle_warns(tmp_path, read):
    path = tmp_path / "cam0.mkv"
    with av.open(str(path), "w") as container:
        stream = container.add_stream("libx264", rate=100)
        stream.width, stream.height, stream.pix_fmt = W, H, "yuv420p"
        for i in (0, 1, 2, 4, 5, 6):  # frame 3 lost
            frame = av.VideoFrame.from_ndarray(square_image(i), format="bgr24")
            frame.pts = i
            container.mux(stream.encode(frame))
        container.mux(stream.encode())
    with pytest.warns(UserWarning, match=r"cam0\.mkv: frame 3 comes 20\.000 ms after frame 2, where frames "
                                         r"come every 10\.000 ms: frames lost"):
        times = list(read(path))
    assert times == [i * FRAME_NS for i in (0, 1, 2, 4, 5, 6)]


@pytest.mark.parametrize("old, new, error", [(b"uint32 height", b"uint32 1eight", "NameError"),
                                             (b"uint32 height", b"uint32 he\xb4ght", "UnicodeDecodeError")])
def test_a_damaged_message_definition_is_named(tmp_path, old, new, error):
    """Issue 37: the ROS 2 message definition parser's own errors escaped naming no file."""
    data = raw_bag(tmp_path / "bag.mcap").read_bytes()
    path = tmp_path / "damaged.mcap"
    path.write_bytes(data.replace(old, new))
    with pytest.raises(CameraStreamError, match=rf"damaged\.mcap: the message definition of /cam0/image_raw "
                                                rf"\(sensor_msgs/msg/Image\) does not parse \({error}"):
        read_all(path)


# Issue 48: a held-out fuzz run's findings, each now a CameraStreamError naming the file and the frame


@pytest.mark.parametrize("read", READERS)
def test_a_ros2_stamp_of_a_second_or_more_of_nanosec_is_named(tmp_path, read):
    """builtin_interfaces/Time keeps whole seconds in sec: nanosec 1.5e9 moved the frame 1.5 s without a
    word."""
    messages = [raw_message(i, t, "bgr8") for i, t in enumerate(TIMES)]
    messages[2]["header"]["stamp"]["nanosec"] += 1_500_000_000
    stamp = messages[2]["header"]["stamp"]
    log_time = stamp["sec"] * 1_000_000_000 + stamp["nanosec"] + 3_000_000 + 137_000 * 2  # as write_bag
    path = write_bag(tmp_path / "bag.mcap", "sensor_msgs/msg/Image", IMAGE_MSGDEF,
                     {"/cam0/image_raw": messages})
    with pytest.raises(CameraStreamError, match=rf"bag\.mcap: frame 2 \(log_time {log_time} ns\) on "
                                                rf"/cam0/image_raw: header stamp nanosec {stamp['nanosec']}; "
                                                r"expected 0 to 999999999"):
        read(path)


@pytest.mark.parametrize("read", READERS)
def test_video_times_beyond_int64_are_named(tmp_path, read):
    """A start_ns near the end of int64 gave an OverflowError naming no file (open_camera_stream)."""
    path = write_video(tmp_path / "cam0.mp4", "mpeg4")
    with pytest.raises(CameraStreamError, match=r"cam0\.mp4: frame 1: start_ns \+ pts x time_base "
                                                r"\(1/\d+ s\) = \d+ does not fit int64"):
        read(path, start_ns=2**63 - 1)
