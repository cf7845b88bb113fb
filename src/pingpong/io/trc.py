"""Marker trajectories as a TRC file (PathFileType 4, "(X/Y/Z)"): what OpenSim's TRCFileAdapter and
Pose2Sim read, and Motion Analysis' Cortex writes.

The layout, tab-separated: line 1 `PathFileType 4 (X/Y/Z) <file name>`; line 2 the header's keys
DataRate CameraRate NumFrames NumMarkers Units OrigDataRate OrigDataStartFrame OrigNumFrames and line 3
their values; line 4 `Frame# Time` and each marker's name followed by two empty cells (its Y and Z);
line 5 two empty cells and X1 Y1 Z1 X2 ... ; a blank line; then one line per frame of exactly 2 + 3 x
markers cells: the frame number (from 1), the time (s) and each marker's X Y Z in the declared unit, empty
cells where it is missing (OpenSim reads a marker with an empty cell as NaN).

OpenSim's ground is y up; the table frame (and Pose2Sim's calibrations) z up. `opensim_axes` turns the
one into the other as Pose2Sim's TRC writer does (X, Y, Z) <- (y, z, x), a rotation, so left stays left.
"""

import os

import numpy as np

from pingpong.common.atomic import write_text_atomic

DECIMALS = 6  # in the file's unit: 1 um in metres


def opensim_axes(points: np.ndarray) -> np.ndarray:
    """(..., 3) z-up points (x, y, z) in OpenSim's y-up axes: (y, z, x)."""
    return np.asarray(points)[..., [1, 2, 0]]


def trc_text(name: str, time_s: np.ndarray, markers: list[str], points: np.ndarray, units: str = "m",
             rate_hz: float | None = None) -> str:
    """The TRC file of markers (M names) at points (F, M, 3) (NaN: missing) at times time_s (F,) (s).

    name: the file name line 1 records. rate_hz: the frame rate (DataRate, CameraRate and
    OrigDataRate); by default from the median frame interval."""
    time_s = np.asarray(time_s, float)
    points = np.asarray(points, float)
    if points.shape != (len(time_s), len(markers), 3):
        raise ValueError(f"points {points.shape} do not fit {len(time_s)} frames of {len(markers)} markers")
    if any(not m or any(c in m for c in "\t\r\n") for m in markers):
        raise ValueError(f"marker names must be non-empty without tabs or line breaks: {markers}")
    if rate_hz is None:
        rate_hz = 1.0 / float(np.median(np.diff(time_s))) if len(time_s) > 1 else 0.0
    n_frames, n_markers = points.shape[:2]
    header = [
        f"PathFileType\t4\t(X/Y/Z)\t{name}",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames",
        f"{rate_hz:.2f}\t{rate_hz:.2f}\t{n_frames}\t{n_markers}\t{units}\t{rate_hz:.2f}\t1\t{n_frames}",
        "Frame#\tTime\t" + "".join(f"{m}\t\t\t" for m in markers),
        "\t\t" + "\t".join(f"X{k}\tY{k}\tZ{k}" for k in range(1, n_markers + 1)),
        "",
    ]
    values = np.char.mod(f"%.{DECIMALS}f", points.reshape(n_frames, -1))
    values[~np.isfinite(points.reshape(n_frames, -1))] = ""
    rows = [f"{f + 1}\t{t:.{DECIMALS}f}\t" + "\t".join(v) for f, (t, v) in enumerate(zip(time_s, values,
                                                                                             strict=True))]
    return "\n".join(header + rows) + "\n"


def write_trc(path: str | os.PathLike, time_s: np.ndarray, markers: list[str], points: np.ndarray,
              units: str = "m", rate_hz: float | None = None) -> None:
    """trc_text written atomically to path (line 1 names the file)."""
    write_text_atomic(path, trc_text(os.path.basename(path), time_s, markers, points, units, rate_hz))
