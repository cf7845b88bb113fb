"""Whether a session's cameras agree on their clock, before anything is triangulated.

Triangulation pairs the views frame by frame, so the cameras must share their frame times (hardware
sync, as in the paper's lab). Per camera: frame count, rate (from the median frame interval), first and
last frame time, and drops (frames missing where an interval is longer than 1.5 median intervals).
Disagreements are errors that name the camera: another rate, another first frame, another count, or
frame times that differ from the first camera's by more than half a frame. Drops alone are warnings:
a frame every camera lost is a gap in every view, which the later stages handle.
"""

import logging

import numpy as np
import pandas as pd

log = logging.getLogger(__name__)

DROP_FACTOR = 1.5  # an interval this many median intervals long or longer has dropped frames
RATE_TOLERANCE = 0.005  # relative: 100 Hz against 100.5 Hz is another camera


class CameraSyncError(ValueError):
    """The cameras of a session do not share a clock."""


def camera_sync_row(camera: str, time_ns: np.ndarray) -> dict:
    """One camera's clock: frames, rate (Hz), first and last time (ns), dropped frames, and the
    intervals (ns) that are not increasing (a file written out of order)."""
    time_ns = np.asarray(time_ns, np.int64)
    if len(time_ns) < 2:  # no interval: no rate (sync_problems names it)
        first = int(time_ns[0]) if len(time_ns) else -1
        return {"camera": camera, "frames": len(time_ns), "rate_hz": np.nan, "first_ns": first,
                "last_ns": first, "dropped_frames": 0, "non_increasing": 0}
    steps = np.diff(time_ns)
    period = float(np.median(steps))
    long = steps[steps >= DROP_FACTOR * period]
    return {"camera": camera, "frames": len(time_ns), "rate_hz": 1e9 / period if period > 0 else np.nan,
            "first_ns": int(time_ns[0]), "last_ns": int(time_ns[-1]),
            "dropped_frames": int(np.round(long / period).sum() - len(long)),
            "non_increasing": int((steps <= 0).sum())}


def sync_table(times: dict[str, np.ndarray]) -> pd.DataFrame:
    """camera_sync_row of every camera, in the given order."""
    return pd.DataFrame([camera_sync_row(camera, t) for camera, t in times.items()])


def sync_problems(times: dict[str, np.ndarray], table: pd.DataFrame) -> tuple[list[str], list[str]]:
    """(errors, warnings), each naming the camera, against the first camera as the reference."""
    errors, warnings = [], []
    ref_name, ref = next(iter(times.items()))
    ref_row = table.iloc[0]
    half_frame = 0.5e9 / ref_row["rate_hz"] if np.isfinite(ref_row["rate_hz"]) else 0.0
    for (camera, t), row in zip(times.items(), table.itertuples(index=False), strict=True):
        if row.frames < 2:
            errors.append(f"{camera}: {row.frames} frame(s); a stream needs at least 2 to have a rate")
            continue
        if row.non_increasing:
            errors.append(f"{camera}: {row.non_increasing} frame time(s) not after the one before")
        if abs(row.rate_hz / ref_row["rate_hz"] - 1) > RATE_TOLERANCE:
            errors.append(f"{camera}: {row.rate_hz:.2f} Hz, {ref_name} {ref_row['rate_hz']:.2f} Hz")
        if abs(row.first_ns - ref_row["first_ns"]) > half_frame:
            errors.append(f"{camera}: first frame {(row.first_ns - ref_row['first_ns']) / 1e6:+.1f} ms from "
                          f"{ref_name}'s")
        if row.frames != ref_row["frames"]:
            errors.append(f"{camera}: {row.frames} frames, {ref_name} {ref_row['frames']}")
        elif np.abs(t - ref).max() > half_frame:
            k = int(np.argmax(np.abs(t - ref) > half_frame))
            errors.append(f"{camera}: frame {k} at {t[k]} ns, {ref_name}'s at {ref[k]} ns")
        if row.dropped_frames:
            warnings.append(f"{camera}: {row.dropped_frames} dropped frame(s)")
    return errors, warnings


def check_sync(times: dict[str, np.ndarray], session: str) -> pd.DataFrame:
    """The sync table of a session's cameras; raises CameraSyncError listing every disagreement, logs
    drops as warnings."""
    table = sync_table(times)
    errors, warnings = sync_problems(times, table)
    for text in warnings:
        log.warning("session %s: %s", session, text)
    if errors:
        raise CameraSyncError(f"session {session}: the cameras do not share a clock (triangulation pairs "
                              "views frame by frame):\n  " + "\n  ".join(errors))
    return table
