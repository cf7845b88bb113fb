"""Paddle poses: OptiTrack rigid bodies resampled onto the camera clock and moved into the table frame.

OptiTrack reports poses in its own world frame at its own rate (>= 120 Hz) with dropouts when
markers are occluded. Positions are interpolated linearly, rotations by slerp; a target time
that falls in a dropout longer than `max_gap_s` or outside the recording is marked invalid
(NaN), never filled in.
"""

import csv
import logging
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation, Slerp

from pingpong.common.artifacts import Schema
from pingpong.common.patterns import TABLE_MARKERS
from pingpong.common.rigid import apply_transform, fit_rigid_transform, rotate_matrices
from pingpong.frames import ROT_COLUMNS
from pingpong.io.mcap_io import read_optitrack

log = logging.getLogger(__name__)

MOTIVE_LENGTH_UNITS_M = {"Meters": 1.0, "Centimeters": 1e-2, "Millimeters": 1e-3}
POSE_COLUMNS = ("x", "y", "z", "qx", "qy", "qz", "qw")


def resample_poses(
    time_ns: np.ndarray,
    positions: np.ndarray,
    quats_xyzw: np.ndarray,
    target_time_ns: np.ndarray,
    max_gap_s: float = 0.05,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poses at target_time_ns (T,) from samples at time_ns (M,): positions (T, 3), rotations (T, 3, 3)
    and valid (T,). Invalid targets (in a gap longer than max_gap_s, or outside the samples) are NaN.

    Unsorted or duplicated sample times are sorted and deduplicated (first sample kept) with a
    warning; samples with NaN (or a zero quaternion) count as dropouts.
    """
    time_ns = np.asarray(time_ns, np.int64)
    positions = np.asarray(positions, float)
    quats = np.asarray(quats_xyzw, float)
    targets = np.asarray(target_time_ns, np.int64)
    if positions.shape != (len(time_ns), 3) or quats.shape != (len(time_ns), 4):
        raise ValueError(f"need positions (M, 3) and quaternions (M, 4) for M={len(time_ns)} times, "
                         f"got {positions.shape} and {quats.shape}")
    if np.any(np.diff(time_ns) < 0):
        warnings.warn("pose timestamps are not sorted; sorting them", stacklevel=2)
    order = np.argsort(time_ns, kind="stable")
    time_ns, positions, quats = time_ns[order], positions[order], quats[order]
    first = np.r_[True, np.diff(time_ns) > 0]
    if not first.all():
        warnings.warn(f"{np.count_nonzero(~first)} duplicated pose timestamps; "
                      "keeping the first sample of each", stacklevel=2)
    good = first & np.isfinite(positions).all(axis=1) & np.isfinite(quats).all(axis=1)
    good &= np.linalg.norm(np.where(np.isfinite(quats), quats, 0.0), axis=1) > 0
    time_ns, positions, quats = time_ns[good], positions[good], quats[good]

    out_positions = np.full((len(targets), 3), np.nan)
    out_rotations = np.full((len(targets), 3, 3), np.nan)
    valid = np.zeros(len(targets), bool)
    if len(time_ns) < 2:
        return out_positions, out_rotations, valid
    i = np.clip(np.searchsorted(time_ns, targets, side="right") - 1, 0, len(time_ns) - 2)
    t0, t1 = time_ns[i], time_ns[i + 1]
    on_sample = (targets == t0) | (targets == t1)
    valid = (targets >= time_ns[0]) & (targets <= time_ns[-1])
    valid &= (t1 - t0 <= round(max_gap_s * 1e9)) | on_sample
    i, t0, t1 = i[valid], t0[valid], t1[valid]
    weight = ((targets[valid] - t0) / (t1 - t0))[:, None]
    out_positions[valid] = (1 - weight) * positions[i] + weight * positions[i + 1]
    # times relative to the first sample, so that float64 holds the nanoseconds exactly
    slerp = Slerp((time_ns - time_ns[0]).astype(float), Rotation.from_quat(quats))
    out_rotations[valid] = slerp((targets[valid] - time_ns[0]).astype(float)).as_matrix()
    return out_positions, out_rotations, valid


def to_table_frame(
    positions: np.ndarray, rotations: np.ndarray, T_table_from_optitrack: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Positions (T, 3) and rotations (T, 3, 3) from OptiTrack's world frame into the table frame."""
    return (apply_transform(T_table_from_optitrack, positions),
            rotate_matrices(T_table_from_optitrack, rotations))


def fit_optitrack_to_table(
    marker_positions_optitrack: np.ndarray, marker_positions_table: np.ndarray
) -> tuple[np.ndarray, float]:
    """T_table_from_optitrack (4x4) from K >= 3 markers measured in both frames, and its RMS residual (m)."""
    T, rms = fit_rigid_transform(marker_positions_optitrack, marker_positions_table)
    log.info("OptiTrack-to-table fit on %d markers: RMS residual %.2f mm",
             len(marker_positions_table), 1e3 * rms)
    return T, rms


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


PADDLE = Schema("paddle", 1, ("time_ns", "player", "px", "py", "pz", *ROT_COLUMNS, "valid"))


def optitrack_to_table(optitrack: dict[str, pd.DataFrame],
                       marker_prefix: str = "table_marker_") -> tuple[np.ndarray, float]:
    """T_table_from_optitrack from the table-corner markers (each marker's median), and its RMS (m)."""
    names = sorted((b for b in optitrack if b.startswith(marker_prefix)),
                   key=lambda b: int(b[len(marker_prefix):]))
    if len(names) < 3:
        raise ValueError(f"need >= 3 table markers '{marker_prefix}<i>' in the OptiTrack stream, "
                         f"found {names}")
    measured = np.array([optitrack[b][["x", "y", "z"]].median().to_numpy() for b in names])
    known = TABLE_MARKERS[[int(b[len(marker_prefix):]) for b in names]]
    return fit_optitrack_to_table(measured, known)


def paddle_table(optitrack: dict[str, pd.DataFrame], bodies: dict[str, str],
                 T_table_from_optitrack: np.ndarray, frame_times_ns: np.ndarray,
                 max_gap_s: float = 0.05) -> pd.DataFrame:
    """Each player's paddle in the table frame on the camera clock; gaps are rows with valid = False."""
    parts = []
    for player, body in bodies.items():
        if body not in optitrack:
            raise ValueError(f"rigid body '{body}' (player '{player}') not in the OptiTrack stream; "
                             f"bodies there: {sorted(optitrack)}")
        df = optitrack[body]
        pos, rot, valid = resample_poses(df["time_ns"].to_numpy(), df[["x", "y", "z"]].to_numpy(),
                                         df[["qx", "qy", "qz", "qw"]].to_numpy(), frame_times_ns, max_gap_s)
        pos, rot = to_table_frame(pos, rot, T_table_from_optitrack)
        parts.append(pd.DataFrame({"time_ns": frame_times_ns, "player": player,
                                   **{f"p{a}": pos[:, k] for k, a in enumerate("xyz")},
                                   **dict(zip(ROT_COLUMNS, rot.reshape(-1, 9).T, strict=True)),
                                   "valid": valid}))
    return pd.concat(parts, ignore_index=True)
