"""OptiTrack rigid-body poses as labs record them: the MCAP stream or a Motive CSV export."""

import csv
from pathlib import Path

import numpy as np
import pandas as pd

from pingpong.io.mcap_io import read_optitrack

MOTIVE_LENGTH_UNITS_M = {"Meters": 1.0, "Centimeters": 1e-2, "Millimeters": 1e-3}
POSE_COLUMNS = ("x", "y", "z", "qx", "qy", "qz", "qw")


def read_motive_csv(path: str | Path) -> dict[str, pd.DataFrame]:
    """Rigid-body poses from an OptiTrack Motive CSV export, by body name.

    Each DataFrame has time_ns (int64, from the take's 'Time (Seconds)' column, so relative to
    the capture start), x, y, z in metres and the quaternion qx, qy, qz, qw; rows where Motive
    lost the body are NaN. Markers, rigid-body markers, bones and error columns are ignored.
    Needs 'Rotation Type,Quaternion' and a 'Length Units' entry in the header line; the take's
    metadata is kept in each frame's attrs.
    """
    path = Path(path)
    with path.open(newline="", encoding="utf-8-sig") as f:
        rows = list(csv.reader(f))
    if not rows or not rows[0] or rows[0][0] != "Format Version":
        raise ValueError(f"{path}: line 1 does not start with 'Format Version'; not a Motive CSV export")
    meta = {k.strip(): v.strip() for k, v in zip(rows[0][0::2], rows[0][1::2], strict=False) if k.strip()}
    if meta.get("Rotation Type") != "Quaternion":
        raise ValueError(f"{path}: line 1: need 'Rotation Type,Quaternion', "
                         f"got {meta.get('Rotation Type')!r}")
    units = meta.get("Length Units")
    if units not in MOTIVE_LENGTH_UNITS_M:
        raise ValueError(f"{path}: line 1: 'Length Units' must be one of {sorted(MOTIVE_LENGTH_UNITS_M)}, "
                         f"got {units!r}")
    scale = MOTIVE_LENGTH_UNITS_M[units]

    axis_line = next((n for n, row in enumerate(rows) if row and row[0] == "Frame"), None)
    if axis_line is None or axis_line < 2:
        raise ValueError(f"{path}: no column header line starting with 'Frame'")
    labelled = {row[1]: row for row in rows[1:axis_line] if len(row) > 1 and row[1]}
    for label in ("Type", "Name"):
        if label not in labelled:
            raise ValueError(f"{path}: missing the '{label}' header line above line {axis_line + 1}")
    axes, components = rows[axis_line], rows[axis_line - 1]
    if len(axes) < 2 or axes[1] != "Time (Seconds)":
        raise ValueError(f"{path}: line {axis_line + 1}: second column must be 'Time (Seconds)'")
    width = len(axes)
    types, names, components = (row + [""] * (width - len(row)) for row in
                                (labelled["Type"], labelled["Name"], components))

    columns: dict[str, dict[str, int]] = {}  # body -> {"x": column, ..., "qw": column}
    for col in range(2, width):
        if types[col] != "Rigid Body" or components[col] not in ("Rotation", "Position"):
            continue
        key = ("q" if components[col] == "Rotation" else "") + axes[col].lower()
        if key not in POSE_COLUMNS:
            raise ValueError(f"{path}: line {axis_line + 1}, column {col + 1}: unexpected axis {axes[col]!r} "
                             f"for {components[col]} of rigid body {names[col]!r}")
        body = columns.setdefault(names[col], {})
        if key in body:
            raise ValueError(f"{path}: rigid body {names[col]!r} has two {key} columns")
        body[key] = col
    for name, body in columns.items():
        missing = [k for k in POSE_COLUMNS if k not in body]
        if missing:
            raise ValueError(f"{path}: rigid body {name!r} lacks the columns {missing}")

    data = [(axis_line + 2 + n, row) for n, row in enumerate(rows[axis_line + 1:]) if row]  # (line, cells)
    times = np.empty(len(data), np.int64)
    values = np.full((len(data), width), np.nan)
    wanted = sorted({col for body in columns.values() for col in body.values()})
    for n, (line, row) in enumerate(data):
        if len(row) < width:
            raise ValueError(f"{path}: line {line} has {len(row)} cells, the header has {width}")
        try:
            times[n] = round(float(row[1]) * 1e9)
            for col in wanted:
                if row[col].strip():
                    values[n, col] = float(row[col])
        except ValueError as err:
            raise ValueError(f"{path}: line {line}: not a number ({err})") from None

    bodies = {}
    for name, body in columns.items():
        frame = pd.DataFrame({"time_ns": times})
        for key in POSE_COLUMNS:
            frame[key] = values[:, body[key]] * (scale if key in ("x", "y", "z") else 1.0)
        frame.attrs = {"source": str(path), **meta}
        bodies[name] = frame
    return bodies


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
        raise ValueError(f"{path}: OptiTrack poses must be an MCAP stream (.mcap) or a Motive CSV export "
                         "(.csv)")
    if take_start_ns is None:
        raise ValueError(f"{path}: a Motive CSV counts time from the take's start; give the camera-clock "
                         "time of its first frame in config lab.motive_take_start_ns (session: ns)")
    bodies = read_motive_csv(path)
    for frame in bodies.values():
        frame["time_ns"] += int(take_start_ns)
    return bodies
