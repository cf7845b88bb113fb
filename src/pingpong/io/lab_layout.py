"""A lab's raw/ folder checked against the config before any job runs (source: lab).

Under `source: lab` the workflow has no rule that writes raw/: a missing recording can only be an
error, and it should be one that names the path and what belongs there, found when the workflow is
read rather than as a missing input of some job deep in the graph. Camera and session names are the
files' own names (`cam_01`, `Camera-A`): they become file names and wildcards, so they are checked
for characters that would make paths ambiguous.
"""

import re
from pathlib import Path

from pingpong.io.calibration_files import (
    BOARD_SHOT,
    TABLE_SHOT,
    VIEWS_STEM,
    CaptureLayoutError,
    extrinsics_shot,
    intrinsics_views,
)

# the camera file formats a lab may hand over (pingpong.io.camera_streams detects which is which)
CAMERA_SUFFIXES = (".mcap", ".mp4", ".avi", ".mkv", ".mov")
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_\-]*")
# file stems of raw/sessions/{session}/ that are not cameras
NOT_CAMERAS = ("optitrack",)


def name_problems(kind: str, names: list[str]) -> list[str]:
    """Why each of `names` (cameras or sessions) cannot name files and wildcards; [] when all can."""
    out = [f"lab.{kind}: {n!r} is not a usable name (letters, digits, '_' and '-', starting with a letter "
           f"or digit)" for n in names if not NAME.fullmatch(n)]
    out += [f"lab.{kind}: {n!r} is reserved for another file" for n in names if n in NOT_CAMERAS]
    out += [f"lab.{kind}: {n!r} is listed twice" for n in sorted({n for n in names if names.count(n) > 1})]
    return out


def camera_recordings(folder: Path) -> dict[str, list[Path]]:
    """The camera recordings in a session folder by camera name (the file's stem)."""
    found: dict[str, list[Path]] = {}
    for path in sorted(folder.iterdir()) if folder.is_dir() else []:
        if path.suffix.lower() in CAMERA_SUFFIXES and path.stem not in NOT_CAMERAS and path.is_file():
            found.setdefault(path.stem, []).append(path)
    return found


def session_problems(root: Path, session: str, cameras: list[str], optitrack: str | None) -> list[str]:
    """What is missing or misnamed in raw/sessions/{session}/: each camera's recording (a camera without
    one is an error, never a camera silently dropped), its OpenPose folder beside it, several recordings
    of one camera, the OptiTrack file (its name, None: none expected)."""
    folder = root / "raw/sessions" / session
    if not folder.is_dir():
        return [f"raw/sessions/{session}/: no such folder (lab.sessions lists {session!r}); expected one "
                f"recording per camera ({', '.join(cameras)}) named {{camera}}{{.mcap|.mp4|.avi|.mkv|.mov}}, "
                f"and openpose/{{camera}}/ beside them"]
    recordings = camera_recordings(folder)
    out = [f"raw/sessions/{session}/: several recordings of {cam}: {[p.name for p in files]}; keep one"
           for cam, files in recordings.items() if cam in cameras and len(files) > 1]
    out += [f"raw/sessions/{session}/{cam}.*: missing; expected camera {cam}'s recording "
            f"({'|'.join(CAMERA_SUFFIXES)}); a session recorded with fewer cameras lists its own in "
            f"lab.session_cameras ({session}: [...])" for cam in cameras if cam not in recordings]
    for cam in (c for c in cameras if c in recordings):
        pose = folder / "openpose" / cam
        if not pose.is_dir() or not any(pose.iterdir()):
            out.append(f"raw/sessions/{session}/openpose/{cam}/: missing or empty; expected the "
                       f"OpenPose-family JSON of {recordings[cam][0].name}, one file per frame")
    if optitrack and not (folder / optitrack).is_file():
        out.append(f"raw/sessions/{session}/{optitrack}: missing; expected the session's OptiTrack poses "
                   f"(lab.optitrack_format: none for a lab without motion capture)")
    return out


def session_cameras_problems(sessions: list[str], cameras: list[str],
                             by_session: dict[str, list[str]]) -> list[str]:
    """lab.session_cameras: each a configured session, each of its cameras configured, two at least (to
    triangulate)."""
    out = [f"lab.session_cameras: {s!r} is not in lab.sessions" for s in by_session if s not in sessions]
    for s, cams in by_session.items():
        out += [f"lab.session_cameras: {s}: {c!r} is not in lab.cameras {cameras}" for c in cams
                if c not in cameras]
        if len(set(cams)) < 2:
            out.append(f"lab.session_cameras: {s}: {cams}; at least two cameras are needed to triangulate")
    return out


def camera_name_problems(root: Path, sessions: list[str], cameras: list[str]) -> list[str]:
    """Configured cameras with a recording in no session while recordings of unlisted names are there:
    misnamed, not only missing; the error lists the files' names."""
    found = {cam for s in sessions for cam in camera_recordings(root / "raw/sessions" / s)}
    absent = [c for c in cameras if c not in found]
    if not absent or found <= set(cameras):
        return []
    return [f"lab.cameras: no session has a recording of {absent} (raw/sessions/{{session}}/{{camera}}"
            f"{{.mcap|.mp4|...}}); the recordings there are named {sorted(found)}: name the cameras as "
            f"the files do"]


# what each camera's extrinsics shot shows, by perception.calibration_extrinsics (points: no shot)
SHOTS = {"table_mat": (TABLE_SHOT, "the camera's view of the table with its calibration mat"),
         "board": (BOARD_SHOT, "the camera's view of the board lying at its configured pose")}


def calibration_problems(root: Path, cameras: list[str], calibration_import: str | None,
                         extrinsics: str = "table_mat") -> list[str]:
    """An imported calibration file that is not there, or, when fitting, a camera without its board views
    or the extrinsics shot the method `extrinsics` (table_mat, board, points) needs."""
    if calibration_import:
        if (root / calibration_import).is_file():
            return []
        return [f"{calibration_import}: missing (perception.calibration_import); expected an OpenCV "
                f"YAML/JSON or Anipose/Pose2Sim TOML calibration"]
    out = []
    for cam in cameras:
        folder = root / "raw/calibration" / cam
        if not intrinsics_views(folder):
            out.append(f"raw/calibration/{cam}/{VIEWS_STEM}*: no views; expected images of the calibration "
                       f"board (perception.calibration_board) in any format OpenCV reads")
        if extrinsics in SHOTS and not extrinsics_shot(folder, SHOTS[extrinsics][0]):
            out.append(f"raw/calibration/{cam}/{SHOTS[extrinsics][0]}.*: missing; expected "
                       f"{SHOTS[extrinsics][1]}, in any format OpenCV reads")
    return out


def lab_layout_problems(root: Path, sessions: list[str], cameras: list[str], optitrack: str | None,
                        calibration_import: str | None, extrinsics: str = "table_mat",
                        session_cameras: dict[str, list[str]] | None = None) -> list[str]:
    """Every problem of a lab's raw/ against the config, each naming the path and what belongs there
    (extrinsics: the kind of perception.calibration_extrinsics; session_cameras: lab.session_cameras,
    the sessions recorded with fewer cameras)."""
    root, by_session = Path(root), session_cameras or {}
    out = name_problems("cameras", cameras) + name_problems("sessions", sessions)
    out += session_cameras_problems(sessions, cameras, by_session)
    if not sessions:
        out.append("lab.sessions: empty; list the sessions under raw/sessions/")
    try:
        out += calibration_problems(root, cameras, calibration_import, extrinsics)
    except CaptureLayoutError as err:  # two formats of one shot
        out.append(str(err))
    out += camera_name_problems(root, sessions, cameras)
    for session in sessions:
        out += session_problems(root, session, by_session.get(session, cameras), optitrack)
    return out
