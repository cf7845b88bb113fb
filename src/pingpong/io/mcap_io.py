"""MCAP files as the lab's recorders write them: camera streams and OptiTrack rigid-body poses.

Camera file `raw/sessions/{s}/cam{c}.mcap`: one channel `/cam{c}/image` of protobuf
`foxglove.CompressedImage` (format "jpeg", frame_id = camera name), log_time = the camera's
timestamp (ns) = the message's `timestamp`. Chunks are stored uncompressed (JPEG does not shrink).

OptiTrack file `raw/sessions/{s}/optitrack.mcap`: one channel per rigid body,
`/optitrack/{body}` (e.g. `paddle_A`, `table_marker_0`), protobuf `foxglove.PoseInFrame` in
frame `optitrack_world` (Motive's y-up world), log_time = OptiTrack's clock (ns); zstd chunks.

Other MCAP files (ROS 2 bags) are listed by `mcap_channels` and read one channel at a time by
`read_channel`, with the same handling of damage.

Writers are context managers that stream messages to a temporary file beside the target and
rename it on a clean exit, so an exception or a kill never leaves a file under the final name.
Readers stream (memory bounded) and, on a truncated or corrupt file, stop at the damage with a
warning naming the file and the last good log_time, or raise `McapDamagedError` when strict; fewer
messages than the summary's statistics count (records lost where the reader skips them, e.g. zeroed)
is damage too. OptiTrack poses must be finite with a unit quaternion (others dropped with a warning). A
log_time beyond int64 ns (MCAP's are uint64) and two channels of one rigid body are McapDamagedErrors.
"""

import contextlib
import io
import os
import struct
import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
from google.protobuf.message import DecodeError
from mcap.opcode import Opcode
from mcap.reader import NonSeekingReader, SeekingReader
from mcap.records import Channel, MessageIndex, Schema
from mcap.stream_reader import StreamReader, get_chunk_data_stream
from mcap.writer import CompressionType
from mcap_protobuf.writer import Writer as ProtobufWriter

from pingpong.common.atomic import atomic_path
from pingpong.io.guards import check_int64, check_unique

OPTITRACK_FRAME = "optitrack_world"
OPTITRACK_PREFIX = "/optitrack/"
POSE_COLUMNS = ["time_ns", "x", "y", "z", "qx", "qy", "qz", "qw"]
QUATERNION_TOLERANCE = 1e-3  # |norm - 1| of a recorded rotation; Motive's 6 decimals give < 1e-5


class McapDamagedError(ValueError):
    """A truncated or corrupt MCAP file (strict reading)."""


def camera_topic(camera_index: int) -> str:
    return f"/cam{camera_index}/image"


class _AtomicMcapWriter:
    """A protobuf MCAP writer on a temporary file, renamed onto `path` on a clean exit."""

    def __init__(self, path: str | os.PathLike, compression: CompressionType):
        self.path = Path(path)
        self._compression = compression
        self._stack = contextlib.ExitStack()

    def __enter__(self):
        tmp = self._stack.enter_context(atomic_path(self.path))
        self._file = self._stack.enter_context(open(tmp, "wb"))
        self._writer = ProtobufWriter(self._file, compression=self._compression)
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self._writer.finish()
        return self._stack.__exit__(exc_type, exc, tb)


class SceneWriter(_AtomicMcapWriter):
    """Write any protobuf messages (foxglove.SceneUpdate, FrameTransforms, ...) and metadata records,
    zstd-compressed: `with SceneWriter(path) as w: w.add(topic, t_ns, message)`."""

    def __init__(self, path: str | os.PathLike):
        super().__init__(path, CompressionType.ZSTD)

    def add(self, topic: str, log_time_ns: int, message) -> None:
        log_time_ns = int(log_time_ns)
        self._writer.write_message(topic, message, log_time=log_time_ns, publish_time=log_time_ns)

    def add_metadata(self, name: str, record: dict[str, str]) -> None:
        self._writer.add_metadata(name, record)


class CameraStreamWriter(_AtomicMcapWriter):
    """Write one camera's JPEG frames: `with CameraStreamWriter(path, 0, "cam0") as w: w.add(t_ns, jpeg)`."""

    def __init__(self, path: str | os.PathLike, camera_index: int, camera_name: str):
        super().__init__(path, CompressionType.NONE)
        self.topic = camera_topic(camera_index)
        self.camera_name = camera_name
        self._last_ns = None

    def add(self, log_time_ns: int, jpeg: bytes) -> None:
        """Append one frame; timestamps must strictly increase."""
        log_time_ns = int(log_time_ns)
        if self._last_ns is not None and log_time_ns <= self._last_ns:
            raise ValueError(f"{self.path}: frame time {log_time_ns} ns does not follow {self._last_ns} ns")
        message = CompressedImage(frame_id=self.camera_name, data=jpeg, format="jpeg")
        message.timestamp.FromNanoseconds(log_time_ns)
        self._writer.write_message(self.topic, message, log_time=log_time_ns, publish_time=log_time_ns)
        self._last_ns = log_time_ns


class OptitrackWriter(_AtomicMcapWriter):
    """Write rigid-body poses: `with OptitrackWriter(path) as w: w.add("paddle_A", t_ns, xyz, quat_xyzw)`.

    Messages must come in non-decreasing log_time over the whole file (as a live stream would).
    """

    def __init__(self, path: str | os.PathLike):
        super().__init__(path, CompressionType.ZSTD)

    def add(self, body: str, log_time_ns: int, position: np.ndarray, quaternion_xyzw: np.ndarray) -> None:
        log_time_ns = int(log_time_ns)
        message = PoseInFrame(frame_id=OPTITRACK_FRAME)
        message.timestamp.FromNanoseconds(log_time_ns)
        message.pose.position.x, message.pose.position.y, message.pose.position.z = map(float, position)
        q = message.pose.orientation
        q.x, q.y, q.z, q.w = map(float, quaternion_xyzw)
        self._writer.write_message(OPTITRACK_PREFIX + body, message, log_time=log_time_ns,
                                   publish_time=log_time_ns)


def _check_schema(path: Path, schema: Schema | None, channel: Channel, schema_name: str,
                  message_encoding: str) -> None:
    """McapDamagedError unless the channel carries `schema_name` messages in `message_encoding`."""
    if schema is None or schema.name != schema_name or channel.message_encoding != message_encoding:
        raise McapDamagedError(
            f"{path}: channel {channel.topic} has schema {None if schema is None else schema.name!r} "
            f"({channel.message_encoding}), expected {message_encoding} {schema_name!r}")


def _iter_messages(path: Path, schema_name: str, strict: bool, what: str, topic: str | None = None,
                   message_encoding: str = "protobuf"):
    """(channel record, log_time, data) of every message (of `topic` alone when given, the others
    skipped), stopping (warning or raising) at damage; a log_time beyond int64 is an error."""
    last_ns = None
    counts: dict[int, int] = {}  # messages read per channel id
    with open(path, "rb") as f:
        reader = NonSeekingReader(f, validate_crcs=True)
        try:
            for schema, channel, message in reader.iter_messages(log_time_order=False):
                if topic is not None and channel.topic != topic:
                    continue
                _check_schema(path, schema, channel, schema_name, message_encoding)
                _check_log_time(path, sum(counts.values()), channel.topic, message.log_time)
                yield channel, message.log_time, message.data
                last_ns = message.log_time
                counts[channel.id] = counts.get(channel.id, 0) + 1
        except McapDamagedError:
            raise
        except Exception as exc:  # the mcap reader signals truncation/corruption with several types
            text = (f"{path}: truncated or corrupt after log_time {last_ns} ns "
                    f"({type(exc).__name__}: {exc}); expected {what} up to a complete MCAP footer")
            if strict:
                raise McapDamagedError(text) from exc
            warnings.warn(text, stacklevel=3)
            return
        missing = _unread_messages(f, counts, topic)
    if missing:
        text = f"{path}: {missing}; expected {what} (records lost, e.g. zeroed, where the reader skips them)"
        if strict:
            raise McapDamagedError(text)
        warnings.warn(text, stacklevel=3)


def _check_log_time(path: Path, index: int, topic: str | None, log_time: int) -> None:
    """MCAP times are uint64; the pipeline's are int64 ns, which numpy would wrap round past 2**63."""
    check_int64(log_time, McapDamagedError, f"{path}: message {index}{f' on {topic}' if topic else ''}: "
                "log_time")


def _unread_messages(f, counts: dict[int, int], topic: str | None) -> str:
    """'' or which channels gave fewer messages than the file's statistics count: damage the streaming
    reader cannot see (it skips records of unknown opcodes, and zeroed bytes read as such)."""
    try:
        f.seek(0)  # the reader checks the magic where the file stands
        summary = SeekingReader(f).get_summary()
    except Exception:  # no summary to compare with: a file written without one
        return ""
    if summary is None or summary.statistics is None:
        return ""
    channels = {cid: c.topic for cid, c in summary.channels.items() if topic is None or c.topic == topic}
    short = [f"{channels[cid]}: {counts.get(cid, 0)} of the {count} messages its statistics count"
             for cid, count in sorted(summary.statistics.channel_message_counts.items())
             if cid in channels and counts.get(cid, 0) < count]
    return "; ".join(short)


def read_camera_stream(path: str | os.PathLike, strict: bool = False,
                       topic: str | None = None) -> Iterator[tuple[int, bytes]]:
    """Stream (log_time_ns, jpeg bytes) of a camera file's frames in file order (of `topic` alone when
    given; otherwise every channel must be a camera channel)."""
    path = Path(path)
    for _, log_time, data in _iter_messages(path, "foxglove.CompressedImage", strict,
                                            "foxglove.CompressedImage frames", topic=topic):
        try:
            message = CompressedImage.FromString(data)
        except DecodeError as exc:
            raise McapDamagedError(f"{path}: frame at {log_time} ns does not decode as "
                                   f"foxglove.CompressedImage ({exc})") from exc
        if message.format not in ("jpeg", "jpg"):
            raise McapDamagedError(f"{path}: frame at {log_time} ns has format {message.format!r}, "
                                   "expected jpeg")
        yield log_time, message.data


def read_optitrack(path: str | os.PathLike, strict: bool = False) -> dict[str, pd.DataFrame]:
    """Poses per rigid body ({body: DataFrame[time_ns, x, y, z, qx, qy, qz, qw]}) in OptiTrack's frame.

    Dropouts are simply missing rows. Time is OptiTrack's log_time in ns (int64).
    """
    path = Path(path)
    rows: dict[str, list] = {}
    channels: dict[int, str] = {}  # channel id -> its body: two channels of one body would interleave
    for channel, log_time, data in _iter_messages(path, "foxglove.PoseInFrame", strict,
                                                  "foxglove.PoseInFrame poses"):
        topic = channel.topic
        if not topic.startswith(OPTITRACK_PREFIX):
            continue
        if channel.id not in channels:
            channels[channel.id] = topic[len(OPTITRACK_PREFIX):]
            check_unique(channels.values(), [f"channel {cid}" for cid in channels], McapDamagedError,
                         str(path), "rigid-body channels")
        try:
            pose = PoseInFrame.FromString(data).pose
        except DecodeError as exc:
            raise McapDamagedError(f"{path}: the pose on {topic} at {log_time} ns does not decode as "
                                   f"foxglove.PoseInFrame ({exc})") from exc
        rows.setdefault(channels[channel.id], []).append(
            (log_time, pose.position.x, pose.position.y, pose.position.z, pose.orientation.x,
             pose.orientation.y, pose.orientation.z, pose.orientation.w))
    if not rows:
        raise McapDamagedError(f"{path}: no rigid-body poses; expected foxglove.PoseInFrame messages on "
                               f"{OPTITRACK_PREFIX}<body> channels")
    return {body: _plausible_poses(path, body, pd.DataFrame(body_rows, columns=POSE_COLUMNS))
            for body, body_rows in rows.items()}


def _plausible_poses(path: Path, body: str, poses: pd.DataFrame) -> pd.DataFrame:
    """The poses with finite values and a unit quaternion; any other dropped (as a dropout) with a warning
    naming the file, the body and the first such time."""
    values = poses[POSE_COLUMNS[1:]].to_numpy()
    norm = np.linalg.norm(values[:, 3:], axis=1)
    bad = ~np.isfinite(values).all(axis=1) | ~(np.abs(norm - 1) < QUATERNION_TOLERANCE)
    if bad.any():
        first = int(np.argmax(bad))
        warnings.warn(f"{path}: {int(bad.sum())} poses of {body} dropped, the first at "
                      f"{poses['time_ns'].iloc[first]} ns ({values[first].tolist()}); expected finite values "
                      "and a unit quaternion", stacklevel=3)
    return poses[~bad].reset_index(drop=True).astype({"time_ns": np.int64})


def read_camera_times(path: str | os.PathLike, strict: bool = False, topic: str | None = None) -> np.ndarray:
    """log_time (ns) of every frame of a camera file, without decoding the images: the camera clock.

    A complete file's times come from its index (summary and message indexes), each entry checked against
    the header of the message it points to, without reading the images: 0.03 s (0.6 s from a cold disk)
    instead of 4 s for a twin camera's 220 MB. Damage inside a chunk's frames is then left to the readers
    of the frames (detection reads every byte, CRCs checked). A file without an index (truncated, or
    written without one), or whose index disagrees with its messages (a warning), is read from the start,
    stopping at damage as read_camera_stream does.
    """
    path = Path(path)
    times = _indexed_times(path, "foxglove.CompressedImage", topic)
    if times is None:
        times = [t for _, t, _ in _iter_messages(path, "foxglove.CompressedImage", strict,
                                                 "foxglove.CompressedImage frames", topic=topic)]
    return np.array(times, dtype=np.int64)


def _indexed_times(path: Path, schema_name: str, topic: str | None,
                   message_encoding: str = "protobuf") -> list[int] | None:
    """log_times of the messages (of `topic` alone when given) in file order, from the file's chunk and
    message indexes; None where the file has no complete index, or (with a warning naming the file) where
    the index disagrees with the messages it points to.

    Message indexes carry no CRC: each entry is checked against the message header at its offset (31
    bytes read per message of an uncompressed chunk; a compressed chunk is decompressed, its CRC checked),
    and the counts against the summary's statistics, before it is believed."""
    with open(path, "rb") as f:
        try:
            summary = SeekingReader(f, validate_crcs=True).get_summary()
        except Exception:  # no footer or summary: truncated or corrupt, read from the start instead
            return None
        chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset) if summary else []
        if not chunks or any(c.message_index_length == 0 for c in chunks):
            return None
        wanted = {cid for c in chunks for cid in c.message_index_offsets
                  if topic is None or summary.channels.get(cid, Channel(cid, 0, "", "", {})).topic == topic}
        for cid in sorted(wanted):
            channel = summary.channels.get(cid)
            if channel is None:
                break  # a chunk index naming an unknown channel: left to the check below
            schema = summary.schemas.get(channel.schema_id)
            _check_schema(path, schema, channel, schema_name, message_encoding)
        try:
            entries = [entry for chunk in chunks for entry in _chunk_entries(f, chunk, wanted)]
            _check_counts(summary, wanted, entries)
        except Exception as exc:  # a damaged index: any parser error, or a disagreement found above
            warnings.warn(f"{path}: its message index disagrees with the file ({type(exc).__name__}: {exc}); "
                          "the times are read from the messages themselves instead", stacklevel=3)
            return None
    times = [t for *_, t in sorted(entries)]
    for index, log_time in enumerate(times):  # as the messages would be checked, had they been read
        _check_log_time(path, index, topic, log_time)
    return times


_MESSAGE_HEADER = struct.Struct("<BQHIQ")  # opcode, record length, channel id, sequence, log_time
# opcode, length, start and end time, uncompressed size and CRC, length of the compression's name
_CHUNK_HEADER = struct.Struct("<BQQQQII")


def _chunk_entries(f, chunk, wanted: set[int]) -> list[tuple[int, int, int]]:
    """(chunk offset, message offset, log_time) of the wanted channels' messages in one chunk, from its
    message indexes, each entry checked against the message header it points to."""
    header_at = _message_headers(f, chunk)
    f.seek(chunk.chunk_start_offset + chunk.chunk_length)
    block = io.BytesIO(f.read(chunk.message_index_length))
    records = StreamReader(block, skip_magic=True).records
    indexes = {}
    while block.tell() < chunk.message_index_length:  # the reader would go on to look for a footer
        at = chunk.chunk_start_offset + chunk.chunk_length + block.tell()
        record = next(records)
        if isinstance(record, MessageIndex):
            if chunk.message_index_offsets.get(record.channel_id) != at:
                raise ValueError(f"a message index of channel {record.channel_id} at offset {at} that the "
                                 "chunk index does not list")
            indexes[record.channel_id] = record
    if indexes.keys() != chunk.message_index_offsets.keys():
        raise ValueError(f"the chunk at offset {chunk.chunk_start_offset} lists message indexes of channels "
                         f"{sorted(chunk.message_index_offsets)}, found {sorted(indexes)}")
    entries = []
    for cid in wanted & indexes.keys():
        for log_time, offset in indexes[cid].records:
            header = header_at(offset)
            found = _MESSAGE_HEADER.unpack(header) if len(header) == _MESSAGE_HEADER.size else None
            if found is None or found[0] != Opcode.MESSAGE or found[2] != cid or found[4] != log_time:
                raise ValueError(f"its entry (channel {cid}, log_time {log_time} ns) points to offset "
                                 f"{offset} of the chunk at {chunk.chunk_start_offset}, which holds no such "
                                 "message")
            entries.append((chunk.chunk_start_offset, offset, log_time))
    return entries


def _message_headers(f, chunk):
    """A function giving the bytes of a message header at an offset of the chunk's records (fewer past
    their end): read from the file where the chunk is uncompressed, else from the decompressed chunk."""
    f.seek(chunk.chunk_start_offset)
    opcode, length, _, _, size, _, name_length = _CHUNK_HEADER.unpack(f.read(_CHUNK_HEADER.size))
    f.seek(name_length, os.SEEK_CUR)
    (records_length,) = struct.unpack("<Q", f.read(8))
    if opcode != Opcode.CHUNK or length != chunk.chunk_length - 9:
        raise ValueError(f"no chunk record at offset {chunk.chunk_start_offset}")
    if name_length:
        f.seek(chunk.chunk_start_offset)
        record = next(StreamReader(io.BytesIO(f.read(chunk.chunk_length)), skip_magic=True,
                                   emit_chunks=True).records)
        stream, _ = get_chunk_data_stream(record, validate_crc=True)
        data = stream.read(size)
        return lambda offset: data[offset:offset + _MESSAGE_HEADER.size]
    if records_length != size:
        raise ValueError(f"the chunk at offset {chunk.chunk_start_offset} holds {records_length} bytes of "
                         f"records, its header says {size}")
    records_start = f.tell()

    def header_at(offset: int) -> bytes:
        f.seek(records_start + offset)
        return f.read(min(_MESSAGE_HEADER.size, max(0, size - offset)))
    return header_at


def _check_counts(summary, wanted: set[int], entries: list) -> None:
    """ValueError unless the entries are as many as the summary's statistics count (where it has them)."""
    counts = summary.statistics.channel_message_counts if summary.statistics else {}
    expected = sum(counts.get(cid, 0) for cid in wanted) if counts else len(entries)
    if expected != len(entries) or len({entry[:2] for entry in entries}) != len(entries):
        raise ValueError(f"{len(entries)} distinct messages indexed, its statistics count {expected}")


def read_channel(path: str | os.PathLike, topic: str, schema_name: str, message_encoding: str,
                 strict: bool = False) -> Iterator[tuple[int, bytes]]:
    """Stream (log_time_ns, message bytes) of one channel in file order, any schema and encoding (e.g. a
    ROS 2 bag's CDR `sensor_msgs/msg/Image`); damage is handled as by the readers above."""
    for _, log_time, data in _iter_messages(Path(path), schema_name, strict, f"{schema_name} messages",
                                            topic=topic, message_encoding=message_encoding):
        yield log_time, data


def mcap_channels(path: str | os.PathLike) -> tuple[dict[str, tuple[Schema | None, str]], str | None]:
    """({topic: (schema record or None, message encoding)}, why the list may be incomplete or None).

    Reads the summary at the end of the file; where there is none (a truncated file, or a writer that
    writes none) the file is scanned from the start up to any damage, which the second value describes.
    """
    path = Path(path)
    with open(path, "rb") as f:
        try:
            summary = SeekingReader(f).get_summary()
        except Exception:  # no footer: truncated or corrupt, scanned below
            summary = None
        if summary is not None and summary.channels:
            return {c.topic: (summary.schemas.get(c.schema_id), c.message_encoding)
                    for c in summary.channels.values()}, None
        f.seek(0)
        schemas: dict[int, Schema] = {}
        channels: dict[str, Channel] = {}
        damage = None
        try:
            for record in StreamReader(f, validate_crcs=True).records:
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels[record.topic] = record
        except Exception as exc:  # the mcap reader signals truncation/corruption with several types
            damage = f"truncated or corrupt ({type(exc).__name__}: {exc})"
    return {t: (schemas.get(c.schema_id), c.message_encoding) for t, c in channels.items()}, damage
