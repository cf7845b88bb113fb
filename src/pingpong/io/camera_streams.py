"""Camera streams in the formats labs record, behind one reader interface.

A stream is an iterator of frames in time order, each a `Frame` (CameraFrame, RawFrame or VideoFrame):
the frame's time on the camera clock (ns) and a `decode(reduction)` that gives the BGR image (uint8,
H x W x 3), at 1/reduction of the full size when asked (reduction 1, 2, 4 or 8), or None with the reason
when the frame does not decode. JPEG shrinks inside the decoder; other images are decoded whole and
shrunk with INTER_AREA to (w // r, h // r). A CameraFrame also has `decode_rows(first, end)`: the image
with only those rows sure to be decoded, which a JPEG with restart markers per MCU row does alone.

Formats, detected from the file's content (never its name) and logged with the file:
- `foxglove_mcap`: MCAP with a protobuf `foxglove.CompressedImage` (JPEG) channel, what the twin writes;
  time = log_time (= the message's timestamp).
- `ros2_compressed`: a ROS 2 bag (MCAP, CDR) with `sensor_msgs/msg/CompressedImage`, format jpeg or png.
- `ros2_raw`: a ROS 2 bag with `sensor_msgs/msg/Image` in bgr8, rgb8 or mono8 (rows `step` bytes apart);
  every other encoding (alpha, 16-bit, float, Bayer, YUV, ...) is refused.
  ROS 2 times are the header stamps: the camera driver's capture time, where log_time is when the
  recorder received the message, later by a transport and queueing delay that varies frame to frame.
- `video`: MP4/MOV, AVI or Matroska/WebM (by magic bytes), any codec FFmpeg decodes, read with PyAV.
  Times: the container's (pts * time_base after the first frame) + `start_ns`, the camera clock's time
  of the first frame, which a video does not carry; or a timestamp CSV (`timestamps=`, one row per
  frame, a `time_ns` column of camera-clock ns), which then wins.

Every unreadable input raises CameraStreamError naming the file (and the frame or record), the libraries'
own errors included, as do times that do not fit int64 ns and a ROS 2 stamp whose nanosec is a second or
more. A truncated or corrupt file warns and ends the stream at the damage, or raises when
strict; so does a video whose frames fall short of the duration its header declares (Matroska declares no
frame count) or come at uneven intervals (frames lost, or a damaged time table).
"""

import contextlib
import logging
import os
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Protocol

import av
import cv2
import numpy as np
import pandas as pd
from mcap.records import Schema
from mcap.well_known import SchemaEncoding
from mcap_ros2.decoder import DecoderFactory

from pingpong.io import mcap_io
from pingpong.io.guards import check_int64
from pingpong.io.jpeg import REDUCED_FLAGS, decode_jpeg, decode_jpeg_rows
from pingpong.io.mcap_io import McapDamagedError

log = logging.getLogger(__name__)

MCAP_MAGIC = b"\x89MCAP0\r\n"
# schema name -> (format name, message encoding)
IMAGE_SCHEMAS = {"foxglove.CompressedImage": ("foxglove_mcap", "protobuf"),
                 "sensor_msgs/msg/CompressedImage": ("ros2_compressed", "cdr"),
                 "sensor_msgs/msg/Image": ("ros2_raw", "cdr")}
RAW_CHANNELS = {"bgr8": 3, "rgb8": 3, "mono8": 1}
SEPARATOR = "=" * 80
# Both image messages begin with the header, so this prefix of theirs decodes the stamp and skips the pixels.
HEADER_ONLY_MSGDEF = (f"std_msgs/Header header\n{SEPARATOR}\nMSG: std_msgs/Header\n"
                      f"builtin_interfaces/Time stamp\nstring frame_id\n{SEPARATOR}\n"
                      "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n")


class CameraStreamError(ValueError):
    """A camera file that cannot be read as a stream of frames."""


class Frame(Protocol):
    """What every frame of a stream offers, whatever its format."""

    time_ns: int

    def decode(self, reduction: int = 1) -> tuple[np.ndarray | None, str]: ...


def _check_reduction(reduction: int) -> None:
    if reduction not in REDUCED_FLAGS:
        raise ValueError(f"reduction {reduction!r}: expected one of {sorted(REDUCED_FLAGS)}")


def _shrink(image: np.ndarray, reduction: int) -> np.ndarray:
    if reduction == 1:
        return image
    height, width = image.shape[:2]
    return cv2.resize(image, (width // reduction, height // reduction), interpolation=cv2.INTER_AREA)


def _decode_png(data: bytes, reduction: int) -> tuple[np.ndarray | None, str]:
    try:
        image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    except cv2.error as err:  # an empty buffer raises rather than returning None
        return None, f"png does not decode ({err})"
    if image is None:
        return None, f"{len(data)} bytes of png do not decode"
    return _shrink(image, reduction), ""


# (image | None, '' or the decoder's complaint); JPEG through decode_jpeg, which reports damage that
# cv2.imdecode would repair silently, and shrinks in the decoder (libjpeg's DCT scaling)
COMPRESSED_DECODERS = {"jpeg": decode_jpeg, "png": _decode_png}


@dataclass(frozen=True)
class CameraFrame:
    """One compressed image: its time (ns, camera clock) and its bytes in `encoding` ('jpeg' or 'png')."""

    time_ns: int
    data: bytes
    encoding: str = "jpeg"

    def __post_init__(self):
        if self.encoding not in COMPRESSED_DECODERS:
            raise ValueError(f"encoding {self.encoding!r}: expected one of {sorted(COMPRESSED_DECODERS)}")

    def decode(self, reduction: int = 1) -> tuple[np.ndarray | None, str]:
        """(BGR image at 1/reduction of the full size, or None; '' or why it did not decode cleanly)."""
        _check_reduction(reduction)
        return COMPRESSED_DECODERS[self.encoding](self.data, reduction)

    def decode_rows(self, first_row: int, end_row: int) -> tuple[np.ndarray | None, str]:
        """decode(1) with only the rows [first_row, end_row) sure to be decoded: a JPEG with a restart
        marker per MCU row decodes just the MCU rows holding them (pingpong.io.jpeg.decode_jpeg_rows)."""
        return decode_jpeg_rows(self.data, first_row, end_row) if self.encoding == "jpeg" else self.decode(1)


@dataclass(frozen=True)
class RawFrame:
    """Uncompressed pixels as sensor_msgs/msg/Image holds them: `height` rows `step` bytes apart (any
    bytes past width * channels are row padding), in `encoding` bgr8, rgb8 or mono8."""

    time_ns: int
    data: bytes
    width: int
    height: int
    step: int
    encoding: str

    def __post_init__(self):
        if self.encoding not in RAW_CHANNELS:
            raise ValueError(f"encoding {self.encoding!r}: expected one of {sorted(RAW_CHANNELS)}")

    def decode(self, reduction: int = 1) -> tuple[np.ndarray | None, str]:
        _check_reduction(reduction)
        channels = RAW_CHANNELS[self.encoding]
        row_bytes = self.width * channels
        if self.width == 0 or self.height == 0:
            return None, f"empty image ({self.width} x {self.height})"
        if self.step < row_bytes:
            return None, f"step {self.step} bytes, shorter than a row of {self.width} {self.encoding} pixels"
        if len(self.data) != self.step * self.height:
            return None, (f"{len(self.data)} bytes, expected step {self.step} x height {self.height} = "
                          f"{self.step * self.height}")
        rows = np.frombuffer(self.data, np.uint8).reshape(self.height, self.step)
        pixels = rows[:, :row_bytes].reshape(self.height, self.width, channels)
        if self.encoding == "rgb8":
            pixels = pixels[..., ::-1]
        elif self.encoding == "mono8":
            pixels = np.repeat(pixels, 3, axis=2)
        return _shrink(np.ascontiguousarray(pixels), reduction), ""


@dataclass(frozen=True)
class VideoFrame:
    """A frame PyAV decoded (FFmpeg's frame, turned into BGR only on decode), or None with why its packet
    gave no image."""

    time_ns: int
    frame: av.VideoFrame | None
    reason: str = ""

    def decode(self, reduction: int = 1) -> tuple[np.ndarray | None, str]:
        _check_reduction(reduction)
        if self.frame is None:
            return None, self.reason
        try:
            image = self.frame.to_ndarray(format="bgr24")
        except (av.FFmpegError, ValueError) as err:  # a pixel format FFmpeg cannot convert
            return None, f"does not convert to BGR ({err})"
        return _shrink(image, reduction), ""


@dataclass(frozen=True)
class _Source:
    """What the file is: its format, and for MCAP the image channel's topic and schema."""

    format: str
    topic: str | None = None
    schema: Schema | None = None


def _video_container(head: bytes) -> str | None:
    if head[4:8] in (b"ftyp", b"moov", b"mdat", b"free", b"wide", b"skip"):
        return "MP4/MOV"
    if head[:4] == b"RIFF" and head[8:12] == b"AVI ":
        return "AVI"
    return "Matroska/WebM" if head[:4] == b"\x1a\x45\xdf\xa3" else None


def _detect(path: Path, topic: str | None) -> _Source:
    if not path.is_file():
        raise CameraStreamError(f"{path}: no such file; expected a camera stream")
    size = path.stat().st_size
    if size == 0:
        raise CameraStreamError(f"{path}: empty file (0 bytes); expected a camera stream (MCAP or video)")
    with open(path, "rb") as f:
        head = f.read(16)
    if head.startswith(MCAP_MAGIC):
        return _detect_mcap(path, topic)
    if MCAP_MAGIC.startswith(head):
        raise CameraStreamError(f"{path}: truncated MCAP ({size} bytes, less than its magic)")
    container = _video_container(head)
    if container is None:
        raise CameraStreamError(f"{path}: foreign format (first bytes {head[:12]!r}); expected an MCAP file "
                                "or a video container (MP4/MOV, AVI, Matroska/WebM)")
    if topic is not None:
        raise CameraStreamError(f"{path}: topic {topic!r} given for a video ({container}), which has none")
    return _Source("video")


def _detect_mcap(path: Path, topic: str | None) -> _Source:
    channels, damage = mcap_io.mcap_channels(path)
    images = {name: entry for name, entry in channels.items()
              if entry[0] is not None and entry[0].name in IMAGE_SCHEMAS}
    if topic is not None:
        if topic not in images:
            raise CameraStreamError(f"{path}: no image topic {topic!r}; its image topics: "
                                    f"{', '.join(sorted(images)) or 'none'}")
        images = {topic: images[topic]}
    if not images:
        found = ", ".join(f"{name}: {None if schema is None else schema.name} ({encoding})"
                          for name, (schema, encoding) in sorted(channels.items())) or "no channels"
        expected = ", ".join(f"{schema} ({encoding})" for schema, (_, encoding) in IMAGE_SCHEMAS.items())
        raise CameraStreamError(f"{path}: MCAP with no camera image channel ({found})"
                                f"{'; ' + damage if damage else ''}; expected one of {expected}")
    if len(images) > 1:
        raise CameraStreamError(f"{path}: {len(images)} image topics ({', '.join(sorted(images))}); "
                                "pass topic= to say which camera to read")
    [(name, (schema, encoding))] = images.items()
    format_name, expected_encoding = IMAGE_SCHEMAS[schema.name]
    if encoding != expected_encoding:
        raise CameraStreamError(f"{path}: channel {name} holds {schema.name} in {encoding}, "
                                f"expected {expected_encoding}")
    if expected_encoding == "cdr" and schema.encoding != SchemaEncoding.ROS2:
        raise CameraStreamError(f"{path}: channel {name}'s schema is in {schema.encoding!r}, expected "
                                f"{SchemaEncoding.ROS2!r} (a .msg definition)")
    return _Source(format_name, name, schema)


def _source(path: Path, topic: str | None, timestamps, start_ns: int) -> _Source:
    source = _detect(path, topic)
    if source.format != "video" and (timestamps is not None or start_ns != 0):
        raise CameraStreamError(f"{path}: {source.format} carries its own camera times; timestamps= and "
                                "start_ns= are for videos")
    log.info("%s: camera stream format %s%s", path, source.format,
             f" (topic {source.topic})" if source.topic else "")
    return source


@contextlib.contextmanager
def _named(path: Path):
    """Every error inside as a CameraStreamError naming the file: the libraries' own (a damaged header's
    UnicodeDecodeError, a damaged message definition's) say neither which file nor what was expected."""
    try:
        yield
    except CameraStreamError:
        raise
    except McapDamagedError as err:
        raise CameraStreamError(str(err)) from err
    except Exception as err:  # noqa: BLE001 - whatever a library raises on damage, named here
        raise CameraStreamError(f"{path}: does not read as a camera stream ({type(err).__name__}: {err}); "
                                "expected an undamaged MCAP or video recording") from err


def _damage(text: str, strict: bool) -> None:
    if strict:
        raise CameraStreamError(text)
    warnings.warn(text, stacklevel=4)


# ---- ROS 2 bags


def _stamp_ns(path: Path, source: _Source, index: int, log_time: int, message) -> int:
    """The header stamp in ns; builtin_interfaces/Time's nanosec must be under a second (sec holds the
    rest), else the frame would take a time up to 4.3 s late without a word."""
    stamp = message.header.stamp
    if not 0 <= stamp.nanosec < 1_000_000_000:
        raise CameraStreamError(f"{path}: frame {index} (log_time {log_time} ns) on {source.topic}: header "
                                f"stamp nanosec {stamp.nanosec}; expected 0 to 999999999 (whole seconds in "
                                "sec)")
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def _ros2_messages(path: Path, source: _Source, schema: Schema, strict: bool):
    """(index, log_time, decoded message) of the image channel, with `schema` as the message definition."""
    try:
        decoder = DecoderFactory().decoder_for("cdr", schema)
    except Exception as err:  # the msgdef parser raises its own types (and NameError) on a damaged text
        raise CameraStreamError(f"{path}: the message definition of {source.topic} ({schema.name}) does not "
                                f"parse ({type(err).__name__}: {err}); expected a ROS 2 .msg definition"
                                ) from err
    messages = mcap_io.read_channel(path, source.topic, source.schema.name, "cdr", strict)
    for index, (log_time, data) in enumerate(messages):
        try:
            message = decoder(data)
        except Exception as err:  # the CDR decoder signals short or malformed data with several types
            raise CameraStreamError(f"{path}: frame {index} (log_time {log_time} ns) on {source.topic} "
                                    f"does not decode as {source.schema.name} ({type(err).__name__}: {err})"
                                    ) from err
        yield index, log_time, message


def _compressed_encoding(image_format: str) -> str | None:
    """'jpeg' or 'png' for a CompressedImage format ('jpeg', 'png', 'bgr8; jpeg compressed bgr8')."""
    text = image_format.lower()
    if "compresseddepth" in text:  # a depth header precedes the PNG
        return None
    return "jpeg" if ("jpeg" in text or "jpg" in text) else "png" if "png" in text else None


def _ros2_frames(path: Path, source: _Source, strict: bool) -> Iterator[Frame]:
    for index, log_time, message in _ros2_messages(path, source, source.schema, strict):
        where = f"{path}: frame {index} on {source.topic}"
        time_ns = _stamp_ns(path, source, index, log_time, message)
        if source.format == "ros2_compressed":
            encoding = _compressed_encoding(message.format)
            if encoding is None:
                raise CameraStreamError(f"{where} has format {message.format!r}; expected jpeg or png")
            yield CameraFrame(time_ns, message.data, encoding)
        else:
            if message.encoding not in RAW_CHANNELS:
                raise CameraStreamError(f"{where} has encoding {message.encoding!r}; expected one of "
                                        f"{', '.join(RAW_CHANNELS)} (alpha, 16-bit, float, Bayer and YUV "
                                        "images are not read)")
            yield RawFrame(time_ns, message.data, message.width, message.height, message.step,
                           message.encoding)


def _ros2_times(path: Path, source: _Source, strict: bool) -> np.ndarray:
    header_only = Schema(id=source.schema.id, name=source.schema.name, encoding=SchemaEncoding.ROS2,
                         data=HEADER_ONLY_MSGDEF.encode())
    messages = _ros2_messages(path, source, header_only, strict)
    return np.array([_stamp_ns(path, source, *entry) for entry in messages], dtype=np.int64)


# ---- videos


def _video_packets(path: Path, strict: bool) -> tuple[list[int], Fraction]:
    """(sorted pts of the first video stream's packets, its time_base), demuxed without decoding."""
    try:
        with av.open(str(path)) as container:
            if not container.streams.video:
                kinds = ", ".join(stream.type for stream in container.streams) or "none"
                raise CameraStreamError(f"{path}: {container.format.name} container with no video stream "
                                        f"(streams: {kinds}); expected one (a truncated or corrupt file "
                                        "can lose it)")
            stream = container.streams.video[0]
            pts: list[int] = []
            try:
                for packet in container.demux(stream):
                    if packet.size == 0:  # the demuxer's end-of-stream marker
                        continue
                    stamp = packet.pts if packet.pts is not None else packet.dts
                    if stamp is None:
                        raise CameraStreamError(f"{path}: frame {len(pts)} (packet) has no timestamp")
                    pts.append(stamp)
            except av.FFmpegError as err:
                _damage(f"{path}: truncated or corrupt after frame {len(pts)} ({err})", strict)
            if stream.frames > len(pts):
                _damage(f"{path}: {len(pts)} of the {stream.frames} frames its header declares: truncated",
                        strict)
            elif pts:
                _check_extent(path, sorted(pts), stream, container.duration, strict)
            time_base = stream.time_base
    except av.FFmpegError as err:
        raise CameraStreamError(f"{path}: does not open as a video ({err}); truncated or corrupt") from err
    if len(set(pts)) != len(pts):
        raise CameraStreamError(f"{path}: frames share timestamps; expected one pts per frame")
    return sorted(pts), time_base


def _check_extent(path: Path, pts: list[int], stream, duration_us: int | None, strict: bool) -> None:
    """Damage unless the frames span the duration the header declares (Matroska declares no frame count)
    and come at even intervals: a lost frame, or a damaged time, leaves a gap or an odd interval."""
    if len(pts) < 2:
        step = 1 / float(stream.average_rate) if stream.average_rate else None
    else:
        steps = np.diff(pts)
        median = float(np.median(steps))
        odd = np.flatnonzero(np.abs(steps - median) > 1 + 0.01 * median)  # 1 tick: rounded rates
        if len(odd):
            i = int(odd[0]) + 1
            gap_ms, median_ms = (float(v * stream.time_base) * 1e3 for v in (steps[i - 1], median))
            _damage(f"{path}: frame {i} comes {gap_ms:.3f} ms after frame {i - 1}, where frames come every "
                    f"{median_ms:.3f} ms: frames lost or a damaged time table (or a variable-rate camera: "
                    "give its timestamps CSV)", strict)
            return
        step = float(median * stream.time_base)
    if not duration_us or not step:
        return
    covered, declared = float((pts[-1] - pts[0]) * stream.time_base) + step, duration_us / 1e6
    if covered < declared - 1.5 * step:
        _damage(f"{path}: {len(pts)} frames cover {covered:.3f} s of the {declared:.3f} s its header "
                f"declares (about {round(declared / step)} frames): truncated or frames lost", strict)


def _container_times(path: Path, pts: list[int], time_base: Fraction, start_ns: int) -> np.ndarray:
    """start_ns + (pts - first pts) * time_base in ns, rounded, in exact integer arithmetic."""
    num, den = time_base.numerator * 1_000_000_000, time_base.denominator
    times = [start_ns + ((p - pts[0]) * num + den // 2) // den for p in pts]
    for i, t in enumerate(times):
        check_int64(t, CameraStreamError, f"{path}: frame {i}: start_ns + pts x time_base ({time_base} s) =")
    return np.array(times, dtype=np.int64)


def _read_timestamps(path: Path) -> np.ndarray:
    """The `time_ns` column of a timestamp CSV (one row per frame, camera-clock ns)."""
    try:
        table = pd.read_csv(path, dtype=str)
    except (OSError, pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as err:
        raise CameraStreamError(f"{path}: not a readable CSV ({err}); expected a header with a time_ns "
                                "column and one row per frame") from err
    if "time_ns" not in table.columns:
        raise CameraStreamError(f"{path}: columns {list(table.columns)}, expected a time_ns column")
    values = table["time_ns"].str.strip()
    valid = values.str.fullmatch(r"-?\d+").fillna(False).to_numpy(bool)
    if not valid.all():
        row = int(np.argmin(valid))
        raise CameraStreamError(f"{path}: row {row + 1} has time_ns {table['time_ns'].iloc[row]!r}, "
                                "expected an integer (ns)")
    times = [int(value) for value in values]
    for row, time_ns in enumerate(times):
        check_int64(time_ns, CameraStreamError, f"{path}: row {row + 1}: time_ns")
    times = np.array(times, dtype=np.int64)
    bad = np.flatnonzero(np.diff(times) <= 0)
    if len(bad):
        row = int(bad[0]) + 2  # rows count from 1 after the header
        raise CameraStreamError(f"{path}: row {row} has time_ns {times[row - 1]}, not after row {row - 1}'s "
                                f"{times[row - 2]}; expected strictly increasing camera times")
    return times


def _video_times(path: Path, strict: bool, timestamps, start_ns: int) -> np.ndarray:
    pts, time_base = _video_packets(path, strict)
    if timestamps is None:
        return _container_times(path, pts, time_base, start_ns)
    times = _read_timestamps(Path(timestamps))
    if len(times) != len(pts):
        raise CameraStreamError(f"{timestamps}: {len(times)} timestamp rows, but video {path} has {len(pts)} "
                                "frames; expected one row per frame")
    return times


def _video_frames(path: Path, times: np.ndarray, strict: bool) -> Iterator[Frame]:
    """Decoded frames, the k-th given the k-th time: decoders give frames in presentation order, while a
    frame's own pts can be wrong (AVI stores decode-order stamps alone, so B-frames get shuffled ones)."""
    index = 0
    with av.open(str(path)) as container:
        packets = container.demux(container.streams.video[0])
        while True:
            try:
                packet = next(packets)
            except StopIteration:
                break
            except av.FFmpegError:  # damage, already reported by _video_packets
                break
            try:
                decoded = packet.decode()
            except av.FFmpegError as err:
                if strict:
                    raise CameraStreamError(f"{path}: frame {index} does not decode ({err})") from err
                decoded = [None]
            for frame in decoded:
                if index == len(times):
                    raise CameraStreamError(f"{path}: the decoder gives more frames than the {len(times)} "
                                            "packets of the container")
                reason = "" if frame is not None else "its packet does not decode"
                yield VideoFrame(int(times[index]), frame, reason)
                index += 1
    for time_ns in times[index:]:  # packets the decoder gave no frame for
        yield VideoFrame(int(time_ns), None, "the decoder gave no frame")


# ---- the interface


def _checked_times(path: Path, times: np.ndarray) -> np.ndarray:
    if len(times) == 0:
        raise CameraStreamError(f"{path}: no frames; expected a camera stream of at least one frame")
    bad = np.flatnonzero(np.diff(times) <= 0)
    if len(bad):
        i = int(bad[0]) + 1
        raise CameraStreamError(f"{path}: frame {i} at {times[i]} ns does not follow frame {i - 1} at "
                                f"{times[i - 1]} ns; expected strictly increasing camera times")
    return times


def _checked_frames(path: Path, frames: Iterator[Frame]) -> Iterator[Frame]:
    """The frames, checked as they pass: strictly increasing times, at least one; damage as this error."""
    count, last_ns = 0, None
    with _named(path):
        for frame in frames:
            if last_ns is not None and frame.time_ns <= last_ns:
                raise CameraStreamError(f"{path}: frame {count} at {frame.time_ns} ns does not follow frame "
                                        f"{count - 1} at {last_ns} ns; expected strictly increasing camera "
                                        "times")
            yield frame
            count, last_ns = count + 1, frame.time_ns
    if count == 0:
        raise CameraStreamError(f"{path}: no frames; expected a camera stream of at least one frame")


def open_camera_stream(path: str | os.PathLike, strict: bool = False,
                       timestamps: str | os.PathLike | None = None, start_ns: int = 0,
                       topic: str | None = None) -> tuple[str, Iterator[Frame]]:
    """(the format's name, the stream of frames) of a camera file; logs the format.

    strict: raise at damage rather than warn and end the stream there (and, for video, at a frame that
    does not decode, rather than giving it as undecodable). timestamps: a video's per-frame times (CSV).
    start_ns: the camera-clock time of a video's first frame, when its times come from the container.
    topic: the image topic of an MCAP file with more than one.
    """
    path = Path(path)
    with _named(path):
        source = _source(path, topic, timestamps, start_ns)
    if source.format == "foxglove_mcap":
        jpegs = mcap_io.read_camera_stream(path, strict, topic=source.topic)
        frames = (CameraFrame(t, data) for t, data in jpegs)
    elif source.format == "video":
        frames = _video_frames(path, _video_times(path, strict, timestamps, start_ns), strict)
    else:
        frames = _ros2_frames(path, source, strict)
    return source.format, _checked_frames(path, frames)


def camera_frame_times(path: str | os.PathLike, strict: bool = False,
                       timestamps: str | os.PathLike | None = None, start_ns: int = 0,
                       topic: str | None = None) -> np.ndarray:
    """The camera-clock time (int64 ns) of every frame that `open_camera_stream` gives, without decoding
    images: MCAP message times or header stamps, a video's demuxed packets or its timestamp CSV."""
    path = Path(path)
    with _named(path):
        source = _source(path, topic, timestamps, start_ns)
        if source.format == "foxglove_mcap":
            times = mcap_io.read_camera_times(path, strict, topic=source.topic)
        elif source.format == "video":
            times = _video_times(path, strict, timestamps, start_ns)
        else:
            times = _ros2_times(path, source, strict)
    return _checked_times(path, times)


def camera_frame_size(path: str | os.PathLike, strict: bool = False,
                      timestamps: str | os.PathLike | None = None, start_ns: int = 0,
                      topic: str | None = None) -> tuple[int, int]:
    """(width, height) in pixels of a camera stream's images, from its first frame that decodes (any format
    `open_camera_stream` reads; its arguments); an error naming the file when no frame decodes."""
    path = Path(path)
    _, frames = open_camera_stream(path, strict, timestamps, start_ns, topic)
    first_reason = None
    try:
        for index, frame in enumerate(frames):
            image, reason = frame.decode(1)
            if image is not None:
                return image.shape[1], image.shape[0]
            first_reason = first_reason or f"frame {index}: {reason}"
    finally:
        frames.close()  # a video's container closes now, not when collected
    raise CameraStreamError(f"{path}: no frame decodes ({first_reason}); expected images to size the stream")


def check_calibrated_size(path: str | os.PathLike, camera, calibration: str | os.PathLike,
                          strict: bool = False, **reading) -> None:
    """An error naming the stream, both sizes and the calibration file unless the stream's frames
    (camera_frame_size; `reading` as open_camera_stream's) have the size `camera` was calibrated at: other
    pixels would land off their calibrated rays."""
    width, height = camera_frame_size(path, strict, **reading)
    if (width, height) != (camera.width, camera.height):
        raise CameraStreamError(f"{path}: frames of {width} x {height} px, but camera {camera.name} is "
                                f"calibrated for {camera.width} x {camera.height} px in {calibration}; "
                                "expected the stream at the calibration's size (not cropped or scaled)")
