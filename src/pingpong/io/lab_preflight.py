"""What a lab's recordings' headers and a small sample can tell against the config, checked before any job
runs (source: lab), beside lab_layout's check of which files are there.

Each would otherwise stop a job after others ran: the calibration's units, camera names (the calibration
job) and world against the scene (triangulation), the declared OpenPose model and a recording's frame size
against its calibration (pose2d), a truncated video (sync). Every check reads little, so that the workflow
can run them at each start: a video's container header and the packets of its last frames, demuxed but
never decoded; an MCAP file's summary and first image; a few of each camera's OpenPose files; the
calibration file, or one board view per camera. Each problem names the file, what was found and what the
config expects. Files that are missing are lab_layout's to report: these checks pass them by.
"""

import os
from pathlib import Path

import av
import numpy as np
from mcap.reader import make_reader

from pingpong.io.calibration_files import intrinsics_views
from pingpong.io.calibration_import import CalibrationFileError
from pingpong.io.camera_streams import IMAGE_SCHEMAS, CameraStreamError, camera_frame_size
from pingpong.io.lab_layout import camera_recordings
from pingpong.io.openpose_json import (
    KeypointsFileError,
    check_declared_model,
    layout_patterns,
    list_frame_files,
    read_model_keypoints,
)
from pingpong.perception.calibration import CalibrationError, read_gray, read_imported_cameras

SAMPLE_FILES = 24  # OpenPose files read per camera and session to judge the declared model (>= 10 people)
# keypoints files past a video's last frame that pose2d leaves out with a warning: markerless-capture tools
# write one; more mean a video shorter than the footage OpenPose saw
EXTRA_FILES = 1
TAIL_PACKETS = 1_000  # the most packets demuxed from a video's last keyframe on (a GOP is rarely 300)
CROP = "perception.frame_crop"


def lab_preflight(root, lab: dict, perception: dict) -> list[str]:
    """Every problem that headers and a sample show in a lab's raw/ under `root` against the config's lab
    and perception sections (validated, defaults filled)."""
    root = Path(root)
    problems, calibrated = calibrated_sizes(root, lab["cameras"], perception)
    problems += scene_problems(perception)
    problems += [f"{CROP}: {cam!r} is not among lab.cameras {lab['cameras']}"
                 for cam in perception["frame_crop"] if cam not in lab["cameras"]]
    for session in lab["sessions"]:
        recordings = camera_recordings(root / "raw/sessions" / session)
        for cam in (c for c in lab["cameras"] if c in recordings):
            problems += recording_problems(root, session, cam, recordings[cam][0], calibrated.get(cam), lab,
                                           perception["frame_crop"].get(cam))
    return problems


# ---- the calibration

def calibrated_sizes(root: Path, cameras: list[str], perception: dict) -> tuple[list[str], dict]:
    """(problems, camera -> ((width, height) px, the file that says so)): an imported calibration read as the
    calibration job reads it (format, units against its camera spacing, perception.calibration_import_names
    against lab.cameras); for a fitted one, each camera's first board view."""
    path = perception["calibration_import"]
    if path is None:
        views = {cam: intrinsics_views(root / "raw/calibration" / cam) for cam in cameras}
        try:
            return [], {cam: (read_gray(v[0]).shape[::-1], v[0]) for cam, v in views.items() if v}
        except CalibrationError as err:
            return [str(err)], {}
    if not (root / path).is_file():
        return [], {}
    try:
        imported = read_imported_cameras(root / path, perception["calibration_import_units"], cameras,
                                         perception["calibration_import_names"])
    except (CalibrationError, CalibrationFileError) as err:
        return [str(err)], {}
    return [], {c.name: ((c.width, c.height), root / path) for c in imported}


def world_frame(perception: dict) -> tuple[str, str]:
    """(the calibration's world: table or lab, the config key that says so)."""
    if perception["calibration_import"] is not None:
        return ("lab" if perception["calibration_import_world"] == "lab" else "table",
                "perception.calibration_import_world")
    method = perception["calibration_extrinsics"]
    return (method.get("frame", "table") if isinstance(method, dict) else "table",
            "perception.calibration_extrinsics.frame")


def scene_problems(perception: dict) -> list[str]:
    """The players scene looks for people at the table's ends, in the table frame: a calibration whose world
    is the lab's own has no table, and triangulation would find nobody."""
    world, key = world_frame(perception)
    if perception["scene"]["mode"] != "players" or world == "table":
        return []
    return [f"perception.scene.mode: players looks for the players at the table's ends in the table frame, "
            f"but the calibration's world is the lab's own ({key}: lab); a pose-only lab sets "
            f"perception.scene: {{mode: subjects, subjects: N}}"]


# ---- one camera's recording of a session

def recording_problems(root: Path, session: str, cam: str, path: Path, calibrated, lab: dict,
                       crop: dict | None) -> list[str]:
    """A recording's frame size against its calibration (calibrated: (size, file) or None, unknown) or its
    crop, its frame count against its OpenPose files and timestamp rows, its OpenPose files' model."""
    try:
        size, frames, truncation = recording_header(path, lab["camera_topics"].get(cam))
    except CameraStreamError as err:
        return [str(err)]
    out = [f"{path}: {truncation}"] if truncation else []
    out += size_problems(path, cam, size, calibrated, crop)
    folder = root / "raw/sessions" / session / "openpose" / cam
    if not folder.is_dir():
        return out
    try:
        names = keypoints_names(folder, lab["openpose_pattern"])
    except (KeypointsFileError, ValueError) as err:
        return [*out, str(err)]
    out += count_problems(path, frames, len(names), folder, path.with_name(f"{cam}_timestamps.csv"))
    return out + model_problems(folder, names, lab["openpose_model"])


def keypoints_names(folder: Path, pattern: str | None) -> list[str]:
    """The names of an OpenPose folder's per-frame files (lab.openpose_pattern), from one listing: the count
    and the model's sample need no more (list_frame_files stats and numbers every file, 0.2 s per 1,000
    files here; the pose2d job checks each frame's file)."""
    patterns = layout_patterns(pattern).values()
    names = sorted(n for n in os.listdir(folder) if any(p.fullmatch(n) for p in patterns))
    if not names:
        list_frame_files(folder, pattern)  # raises, naming the layouts it expected and a name it found
    return names


def recording_header(path: Path, topic: str | None) -> tuple[tuple[int, int], int | None, str]:
    """((width, height) px, the frames its header promises (None: it does not say), '' or how its data fall
    short of them) of a camera recording, from the container's header (a video) or summary and first image
    (MCAP)."""
    with open(path, "rb") as f:
        is_mcap = f.read(8) == b"\x89MCAP0\r\n"
    if is_mcap:
        return camera_frame_size(path, topic=topic), mcap_frames(path, topic), ""
    try:
        with av.open(str(path)) as container:
            if not container.streams.video:
                raise CameraStreamError(f"{path}: no video stream")
            stream = container.streams.video[0]
            frames = stream.frames or round((container.duration or 0) / 1e6 * float(stream.average_rate or 0))
            return (stream.width, stream.height), frames or None, video_tail(container, stream, frames)
    except av.FFmpegError as err:
        raise CameraStreamError(f"{path}: does not open as a video ({err}); truncated or corrupt") from err


def video_tail(container, stream, frames: int) -> str:
    """'' when the video's data reach the last frame its header promises, else how far they reach: demuxes
    the packets from the keyframe before that frame on (never decodes)."""
    if not frames or not stream.average_rate:
        return ""
    step = 1 / (stream.average_rate * stream.time_base)  # time_base ticks per frame
    start = stream.start_time or 0
    container.seek(int(start + (frames - 1) * step), stream=stream, backward=True)
    last = None
    for count, packet in enumerate(container.demux(stream)):
        stamp = packet.pts if packet.pts is not None else packet.dts
        if packet.size and stamp is not None:
            last = stamp if last is None else max(last, stamp)
        if count == TAIL_PACKETS:
            return ""  # too far to tell cheaply; the sync job counts every packet
    reached = None if last is None else round((last - start) / step) + 1
    if reached is not None and reached >= frames:
        return ""
    where = "no data near its end" if reached is None else f"data up to frame {reached - 1} only"
    return (f"its header promises {frames} frames, but it has {where}: truncated (copied or recorded "
            "short?); expected the whole recording")


def mcap_frames(path: Path, topic: str | None) -> int | None:
    """The image messages an MCAP file's summary counts (None: no summary, e.g. a writer that keeps none)."""
    with open(path, "rb") as f:
        try:
            summary = make_reader(f).get_summary()
        except Exception:  # no readable summary: the stream's own reader reports the damage
            return None
    if summary is None or summary.statistics is None:
        return None
    counts = summary.statistics.channel_message_counts
    images = [cid for cid, c in summary.channels.items() if (topic is None or c.topic == topic)
              and summary.schemas.get(c.schema_id) and summary.schemas[c.schema_id].name in IMAGE_SCHEMAS]
    return sum(counts.get(cid, 0) for cid in images) if len(images) == 1 else None


def size_problems(name: Path, cam: str, size: tuple[int, int], calibrated, crop: dict | None) -> list[str]:
    """A recording's frames against the size its camera was calibrated at, or the crop's."""
    if crop is not None:
        if size == (crop["width"], crop["height"]):
            return []
        return [f"{name}: frames of {size[0]} x {size[1]} px, but {CROP}.{cam} says {crop['width']} x "
                f"{crop['height']} px; expected the window's size"]
    if calibrated is None or size == tuple(calibrated[0]):
        return []
    (width, height), where = calibrated
    return [f"{name}: frames of {size[0]} x {size[1]} px, but camera {cam} is calibrated for {width} x "
            f"{height} px in {where}; expected the recording at the calibration's size, or {CROP}.{cam}: "
            f"{{x, y, width: {size[0]}, height: {size[1]}}} saying where its frames lie in the calibrated "
            "image"]


def count_problems(name: Path, frames: int | None, files: int, folder: Path, timestamps: Path) -> list[str]:
    """The frames a recording's header promises against its OpenPose files (one per frame, EXTRA_FILES more
    allowed) and its timestamp CSV's rows (one per frame)."""
    if frames is None:
        return []
    out = []
    if not frames <= files <= frames + EXTRA_FILES:
        out.append(f"{name}: its header promises {frames} frames, but {folder}/ holds {files} keypoints "
                   f"files; expected one per frame ({EXTRA_FILES} more allowed): is the video truncated, or "
                   "the folder another video's?")
    if timestamps.is_file():
        with open(timestamps, "rb") as f:
            rows = sum(1 for line in f if line.strip()) - 1  # less the header
        if rows != frames:
            out.append(f"{timestamps}: {rows} rows, but {name}'s header "
                       f"promises {frames} frames; expected one row per frame")
    return out


def model_problems(folder: Path, names: list[str], model: str) -> list[str]:
    """The declared OpenPose model checked on SAMPLE_FILES of a folder's files, spread over it."""
    sample = [folder / name for name in names[::max(1, len(names) // SAMPLE_FILES)][:SAMPLE_FILES]]
    try:
        people = [read_model_keypoints(p, model) for p in sample]
        most = max(len(p) for p in people)
        raw = np.zeros((len(people), most, people[0].shape[1], 3))
        for i, p in enumerate(people):
            raw[i, :len(p)] = p
        check_declared_model(raw, model, sample)
    except (KeypointsFileError, ValueError) as err:
        return [str(err)]
    return []

