"""OptiTrack rigid-body poses as labs record them: the MCAP stream or a Motive CSV export.

A damaged export is an OptitrackError naming the file and line (a cell that is not a finite number, times
that do not increase or do not fit int64 ns, two rigid bodies of one name, a line the csv module or UTF-8
refuses), or a warning naming them (a frame number skipped or fewer rows than the header declares: rows
lost; a pose with only some cells or a quaternion not of unit length: set lost)."""

import csv
import math
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from pingpong.io.guards import check_int64, check_unique
from pingpong.io.mcap_io import QUATERNION_TOLERANCE, read_optitrack

MOTIVE_LENGTH_UNITS_M = {"Meters": 1.0, "Centimeters": 1e-2, "Millimeters": 1e-3}
POSE_COLUMNS = ("x", "y", "z", "qx", "qy", "qz", "qw")


class OptitrackError(ValueError):
    """OptiTrack poses that cannot be read: the file, the line and what was expected."""


def read_motive_csv(path: str | Path) -> dict[str, pd.DataFrame]:
    """Rigid-body poses from an OptiTrack Motive CSV export, by body name.

    Each DataFrame has time_ns (int64, from the take's 'Time (Seconds)' column, so relative to
    the capture start), x, y, z in metres and the quaternion qx, qy, qz, qw; rows where Motive
    lost the body are NaN. Markers, rigid-body markers, bones and error columns are ignored.
    Needs 'Rotation Type,Quaternion' and a 'Length Units' entry in the header line; the take's
    metadata is kept in each frame's attrs.
    """
    path = Path(path)
    rows = _csv_rows(path)
    if not rows or not rows[0] or rows[0][0] != "Format Version":
        raise OptitrackError(f"{path}: line 1 does not start with 'Format Version'; not a Motive CSV export")
    meta = {k.strip(): v.strip() for k, v in zip(rows[0][0::2], rows[0][1::2], strict=False) if k.strip()}
    if meta.get("Rotation Type") != "Quaternion":
        raise OptitrackError(f"{path}: line 1: need 'Rotation Type,Quaternion', "
                         f"got {meta.get('Rotation Type')!r}")
    units = meta.get("Length Units")
    if units not in MOTIVE_LENGTH_UNITS_M:
        raise OptitrackError(f"{path}: line 1: 'Length Units' must be one of "
                             f"{sorted(MOTIVE_LENGTH_UNITS_M)}, got {units!r}")
    scale = MOTIVE_LENGTH_UNITS_M[units]

    axis_line = next((n for n, row in enumerate(rows) if row and row[0] == "Frame"), None)
    if axis_line is None or axis_line < 2:
        raise OptitrackError(f"{path}: no column header line starting with 'Frame'")
    labelled = {row[1]: row for row in rows[1:axis_line] if len(row) > 1 and row[1]}
    for label in ("Type", "Name"):
        if label not in labelled:
            raise OptitrackError(f"{path}: missing the '{label}' header line above line {axis_line + 1}")
    axes, components = rows[axis_line], rows[axis_line - 1]
    if len(axes) < 2 or axes[1] != "Time (Seconds)":
        raise OptitrackError(f"{path}: line {axis_line + 1}: second column must be 'Time (Seconds)'")
    width = len(axes)
    types, names, ids, components = (row + [""] * (width - len(row)) for row in
                                     (labelled["Type"], labelled["Name"], labelled.get("ID", []), components))
    _check_body_names(path, types, names, ids)

    columns: dict[str, dict[str, int]] = {}  # body -> {"x": column, ..., "qw": column}
    for col in range(2, width):
        if types[col] != "Rigid Body" or components[col] not in ("Rotation", "Position"):
            continue
        key = ("q" if components[col] == "Rotation" else "") + axes[col].lower()
        if key not in POSE_COLUMNS:
            raise OptitrackError(f"{path}: line {axis_line + 1}, column {col + 1}: unexpected axis "
                                 f"{axes[col]!r} for {components[col]} of rigid body {names[col]!r}")
        body = columns.setdefault(names[col], {})
        if key in body:
            raise OptitrackError(f"{path}: rigid body {names[col]!r} has two {key} columns")
        body[key] = col
    for name, body in columns.items():
        missing = [k for k in POSE_COLUMNS if k not in body]
        if missing:
            raise OptitrackError(f"{path}: rigid body {name!r} lacks the columns {missing}")

    data = [(axis_line + 2 + n, row) for n, row in enumerate(rows[axis_line + 1:]) if row]  # (line, cells)
    wanted = sorted({col for body in columns.values() for col in body.values()})
    frames, times, values = _data_rows(path, data, width, wanted)
    _check_frames(path, [line for line, _ in data], frames, times, meta.get("Total Exported Frames"))

    bodies = {}
    for name, body in columns.items():
        frame = pd.DataFrame({"time_ns": times})
        for key in POSE_COLUMNS:
            frame[key] = values[:, body[key]] * (scale if key in ("x", "y", "z") else 1.0)
        _mark_implausible(path, name, frame, [line for line, _ in data])
        frame.attrs = {"source": str(path), **meta}
        bodies[name] = frame
    return bodies


def _check_body_names(path: Path, types: list[str], names: list[str], ids: list[str]) -> None:
    """Two rigid bodies of one name (told apart by their IDs, where the export has an ID line) would read
    as one body's poses."""
    bodies = dict.fromkeys((name, body_id) for kind, name, body_id in zip(types, names, ids, strict=True)
                           if kind == "Rigid Body")
    check_unique([name for name, _ in bodies], [f"ID {body_id}" for _, body_id in bodies], OptitrackError,
                 f"{path}: the Name line", "rigid bodies")


def _csv_rows(path: Path) -> list[list[str]]:
    try:
        with path.open(newline="", encoding="utf-8-sig") as f:
            reader = csv.reader(f)
            try:
                return list(reader)
            except csv.Error as err:
                raise OptitrackError(f"{path}: line {reader.line_num}: {err}; expected a Motive CSV export"
                                     ) from None
    except UnicodeDecodeError as err:
        raise OptitrackError(f"{path}: byte {err.start} is not UTF-8 ({err.reason}); expected a Motive CSV "
                             "export (text)") from None


def _number(path: Path, line: int, column: int, text: str) -> float:
    """A finite number of a cell, or an error naming the file, line and column."""
    try:
        value = float(text)
    except ValueError:
        raise OptitrackError(f"{path}: line {line}: not a number ({text!r} in column {column + 1}); expected "
                             "a finite number") from None
    if not math.isfinite(value):
        raise OptitrackError(f"{path}: line {line}: {text!r} in column {column + 1} is not finite; "
                             "expected a finite number")
    return value


def _data_rows(path: Path, data: list, width: int, wanted: list[int]):
    """(frame numbers, times in ns, values (rows x columns, NaN where empty)) of the data lines."""
    frames = np.empty(len(data), np.int64)
    times = np.empty(len(data), np.int64)
    values = np.full((len(data), width), np.nan)
    for n, (line, row) in enumerate(data):
        if len(row) < width:
            raise OptitrackError(f"{path}: line {line} has {len(row)} cells, the header has {width}")
        frame = _number(path, line, 0, row[0])
        if frame != int(frame) or frame < 0:
            raise OptitrackError(f"{path}: line {line}, column 1: frame {row[0]!r}; expected a frame number")
        frames[n] = int(frame)
        times[n] = round(check_int64(_number(path, line, 1, row[1]) * 1e9, OptitrackError,
                                     f"{path}: line {line}: time {row[1]!r} s in ns:"))
        for col in wanted:
            if row[col].strip():
                values[n, col] = _number(path, line, col, row[col])
    return frames, times, values


def _check_frames(path: Path, lines: list[int], frames: np.ndarray, times: np.ndarray,
                  declared: str | None) -> None:
    """Times must increase (an error naming the line); a frame number skipped, or fewer rows than the
    header's 'Total Exported Frames', warns naming the file (rows lost from the export)."""
    back = np.flatnonzero(np.diff(times) <= 0)
    if len(back):
        n = int(back[0]) + 1
        raise OptitrackError(f"{path}: line {lines[n]}: time {times[n] / 1e9:.6f} s does not follow line "
                             f"{lines[n - 1]}'s {times[n - 1] / 1e9:.6f} s; expected increasing times")
    skipped = np.flatnonzero(np.diff(frames) != 1)
    if len(skipped):
        n = int(skipped[0]) + 1
        warnings.warn(f"{path}: line {lines[n]}: frame {frames[n]} follows frame {frames[n - 1]}; expected "
                      "consecutive frames (rows lost from the export)", stacklevel=4)
    elif declared is not None and declared.isdigit() and int(declared) != len(frames):
        warnings.warn(f"{path}: {len(frames)} rows of frames, its header declares {declared} (Total Exported "
                      "Frames); rows lost from the export", stacklevel=4)


def _mark_implausible(path: Path, name: str, frame: pd.DataFrame, lines: list[int]) -> None:
    """Rows with only some of the pose's cells, or a quaternion that is not of unit length, set lost (NaN)
    with a warning naming the file, the body and the first such line."""
    values = frame[list(POSE_COLUMNS)].to_numpy()
    present = np.isfinite(values)
    norm = np.linalg.norm(values[:, 3:], axis=1)
    bad = (present.any(axis=1) & ~present.all(axis=1)) | (present.all(axis=1) &
                                                          ~(np.abs(norm - 1) < QUATERNION_TOLERANCE))
    if bad.any():
        first = int(np.argmax(bad))
        warnings.warn(f"{path}: line {lines[first]}: rigid body {name!r} has pose {values[first].tolist()}; "
                      f"expected all seven cells and a unit quaternion ({int(bad.sum())} such rows, set "
                      "lost)",
                      stacklevel=4)
        frame.loc[bad, list(POSE_COLUMNS)] = np.nan


def read_optitrack_poses(path: str | Path, strict: bool = False,
                         take_start_ns: int | None = None) -> dict[str, pd.DataFrame]:
    """Rigid-body poses by body name (time_ns on the camera clock, x, y, z, qx, qy, qz, qw) from the
    OptiTrack MCAP stream (`.mcap`) or a Motive CSV export (`.csv`).

    A Motive export counts time from the take's start, so take_start_ns, the camera-clock time of the
    take's first frame (config `lab.motive_take_start_ns`, from the lab's clock sync), is added to it.
    """
    path = Path(path)
    if path.suffix == ".mcap":
        return read_optitrack(path, strict=strict)
    if path.suffix != ".csv":
        raise OptitrackError(f"{path}: OptiTrack poses must be an MCAP stream (.mcap) or a Motive CSV export "
                         "(.csv)")
    if take_start_ns is None:
        raise OptitrackError(f"{path}: a Motive CSV counts time from the take's start; give the camera-clock "
                         "time of its first frame in config lab.motive_take_start_ns (session: ns)")
    bodies = read_motive_csv(path)
    for frame in bodies.values():
        for end in (frame["time_ns"].iloc[[0, -1]] if len(frame) else []):  # times increase
            check_int64(int(end) + int(take_start_ns), OptitrackError,
                        f"{path}: the take's time {int(end)} ns + lab.motive_take_start_ns {take_start_ns} =")
        frame["time_ns"] += int(take_start_ns)
    return bodies
