"""The filtering rule's code: a session's ball and pose cleaned and low-passed (filter_session), by
zero-phase filtering that respects events and NaN gaps.

A Butterworth filter run forwards and backwards (scipy.signal.sosfiltfilt) has no phase lag, but it
smears a discontinuity over ~1/cutoff s: a bounce or a hit would be rounded off and moved. So the
ball signal is cut at its events and each piece between them is filtered on its own; the sample at
an event is the contact itself, on neither smooth piece, and is kept as measured. NaN gaps cut
pieces too (a filter never runs across missing samples) and stay NaN.

Each piece is padded at both ends with the quadratic (in time) fitted to its first / last
~1.5 / cutoff s, instead of sosfiltfilt's odd reflection: the Butterworth response is maximally flat,
so a zero-phase pass leaves polynomials of degree < 2 * order (nearly) unchanged, and a ball's free
flight (a parabola, drag and Magnus slowly bending it) then passes through, ends included. Odd
reflection turns the curvature over at the ends: on some real MPI flights (10 Hz) it pulled the
samples next to a bounce ~7 mm below the lowest measured one and moved the detected bounce by a frame.
The same padding lets any piece of 4 or more samples be filtered: one shorter than the fit window
comes out as (nearly) its least-squares quadratic, which is the ball's flight over such a short piece;
pieces of 1-3 samples are kept as measured.
"""

from functools import lru_cache

import numpy as np
import pandas as pd
from scipy.signal import butter, sosfiltfilt

from pingpong.curation.events import (
    detect_events,
    drop_ball_outliers,
)
from pingpong.curation.tracks import JOINT_VIEWS, JOINT_XYZ, frame_seconds, runs
from pingpong.frames import MODEL_BONES, MODEL_JOINT_IDS

MIN_PIECE_SAMPLES = 4  # a quadratic through 3 samples is the samples themselves
DEFAULT_PADLEN = 15  # sosfiltfilt's own padding for a 4th-order filter, the least used here


@lru_cache(maxsize=64)
def _butter_sos(order: int, cutoff_hz: float, fs_hz: float) -> np.ndarray:
    """Butterworth sections, designed once per setting: a session has thousands of pieces."""
    return butter(order, cutoff_hz, fs=fs_hz, output="sos")


def _quadratic(k: np.ndarray, values: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Least-squares quadratics in k of each row of values (m, len(k)), evaluated at `at`: (m, len(at))."""
    coeffs = np.polynomial.polynomial.polyfit(k, values.T, 2)  # (3, m)
    return np.polynomial.polynomial.polyval(at, coeffs)


def _smooth_uniform(values: np.ndarray, cutoff_hz: float, fs_hz: float, order: int) -> np.ndarray:
    """Uniformly sampled pieces of one length, rows of values (m, n), low-passed with quadratic end pads.

    The pieces' own least-squares quadratics are taken out first and added back after: they pass the
    filter anyway, and without that the filter's start-up on a sloped signal leaves ~1e-5 m at the ends.
    """
    n = values.shape[1]
    if n < MIN_PIECE_SAMPLES:
        return values.copy()
    k = np.arange(n, dtype=float)
    trend = _quadratic(k, values, k)
    rest = values - trend
    fit_len = min(n, max(6, int(round(1.5 * fs_hz / cutoff_hz))))
    pad = max(DEFAULT_PADLEN, int(round(3 * fs_hz / cutoff_hz)))  # ~ the filter's settling time
    head = _quadratic(k[:fit_len], rest[:, :fit_len], np.arange(-pad, 0.0))
    tail = _quadratic(k[n - fit_len:], rest[:, n - fit_len:], np.arange(n, n + pad, dtype=float))
    sos = _butter_sos(order, float(cutoff_hz), float(fs_hz))
    padded = np.concatenate([head, rest, tail], axis=1)
    return trend + sosfiltfilt(sos, padded, axis=1, padtype=None)[:, pad:pad + n]


def _smooth_irregular(times: np.ndarray, values: np.ndarray, cutoff_hz: float, fs_hz: float,
                      order: int) -> np.ndarray:
    """One irregularly sampled piece (n,) (real trackers drop ticks), filtered on a uniform grid spanning
    it at ~fs_hz, interpolated linearly there and back."""
    n_grid = int(round((times[-1] - times[0]) * fs_hz)) + 1
    if n_grid < MIN_PIECE_SAMPLES:
        return values.copy()
    grid = np.linspace(times[0], times[-1], n_grid)
    grid_fs = (n_grid - 1) / (times[-1] - times[0])  # the end points stay exact, so fs moves a little
    smoothed = _smooth_uniform(np.interp(grid, times, values)[None], min(cutoff_hz, 0.45 * grid_fs),
                               grid_fs, order)[0]
    return np.interp(times, grid, smoothed)


def lowpass_between_events(times_s, signal, event_indices, cutoff_hz: float, fs_hz: float = 100.0,
                           order: int = 4) -> np.ndarray:
    """Signal (T, D) or (T,) low-passed column by column, each piece between events and NaN gaps alone.

    times_s (T,) increasing sample times (s); event_indices: samples of hits and bounces, which split the
    pieces and keep their measured values; cutoff_hz: the Butterworth -3 dB frequency (applied twice by
    the zero-phase filter); fs_hz: the sampling rate the filter is designed for (irregular times are
    resampled to it per piece). NaN samples stay NaN. Uniformly sampled pieces of equal length are
    filtered together in one vectorised call (a session has thousands of pieces).
    """
    times = np.asarray(times_s, dtype=float)
    values = np.asarray(signal, dtype=float)
    flat = values.reshape(len(values), -1)
    if len(times) != len(flat):
        raise ValueError(f"times ({len(times)}) and signal ({len(flat)}) differ in length")
    if not 0 < cutoff_hz < fs_hz / 2:
        raise ValueError(f"cutoff {cutoff_hz} Hz must lie in (0, {fs_hz / 2}) Hz (Nyquist at fs {fs_hz} Hz)")
    at_event = np.zeros(len(flat), dtype=bool)
    at_event[np.asarray(event_indices, dtype=int)] = True
    # irregular steps before each sample, cumulated, so a piece's regularity is one subtraction
    irregular = np.concatenate([[0], np.cumsum(~np.isclose(np.diff(times), 1.0 / fs_hz, rtol=0.02))])
    out = flat.copy()
    uniform_pieces: dict[int, list[tuple[int, int]]] = {}  # length -> (column, start)
    for col in range(flat.shape[1]):
        for start, stop in zip(*runs(np.isfinite(flat[:, col]) & ~at_event), strict=True):
            if irregular[stop - 1] == irregular[start]:
                uniform_pieces.setdefault(stop - start, []).append((col, start))
            else:
                out[start:stop, col] = _smooth_irregular(times[start:stop], flat[start:stop, col], cutoff_hz,
                                                         fs_hz, order)
    for length, pieces in uniform_pieces.items():
        cols, starts = np.array(pieces).T
        rows = starts[:, None] + np.arange(length)
        out[rows, cols[:, None]] = _smooth_uniform(flat[rows, cols[:, None]], cutoff_hz, fs_hz, order)
    return out.reshape(values.shape)


def lowpass(signal, cutoff_hz: float, fs_hz: float = 100.0, order: int = 4) -> np.ndarray:
    """Uniformly sampled signal (T, D) or (T,) low-passed (zero phase) column by column; NaN gaps split
    the pieces and stay NaN. For pose signals, which have no events."""
    n = len(signal)
    return lowpass_between_events(np.arange(n) / fs_hz, signal, [], cutoff_hz, fs_hz, order)


# pairs of model joints (positions in MODEL_JOINT_IDS) whose distance is a rigid bone or the torso's width

# A bone's length is wrong beyond this many robust standard deviations of its own scatter. With a detector's
# errors (the twin's COCO-sigma keypoints, issue 41) bone lengths scatter by a median 2.6-3.9 cm and the fixed
# 10 cm tolerance alone removed 8.8 % of a tiny run's wrist frames (a bone's noise, not a wrong joint);
# a joint thrown onto the other arm or person is off by the shoulders' width (~0.35 m) or more.
BONE_NOISE_SIGMAS = 4.0


def clean_pose(pose3d: pd.DataFrame, max_bone_error: float = 0.10, causal: bool = False,
               window_s: float = 10.0) -> pd.DataFrame:
    """pose3d with bad joints removed (coordinates NaN, views 0): a joint is bad on a frame where every
    bone (frames.MODEL_BONES) it belongs to is longer or shorter than that bone's median over the
    player's session by more than its tolerance, e.g. a joint triangulated onto the other arm or another
    person. The tolerance is max_bone_error (m) or BONE_NOISE_SIGMAS robust standard deviations (1.4826 x
    the median absolute deviation) of that bone's length, whichever is larger, so that a detector's
    ordinary noise is not read as a wrong joint. On the raw pose, before the low-pass, which would smear
    one such frame over its neighbours.

    causal: the median is the bone's over the player's frames of the last window_s s up to and with
    the frame itself, so no decision depends on a later frame (as live). It checks little on a player's
    first frames, whose reference is those frames themselves.
    """
    out = pose3d.copy()
    for player in out["player"].unique():
        rows = (out["player"] == player).to_numpy()
        joints = out.loc[rows, JOINT_XYZ].to_numpy(float).reshape(-1, len(MODEL_JOINT_IDS), 3)
        lengths = np.stack([np.linalg.norm(joints[:, a] - joints[:, b], axis=1) for a, b in MODEL_BONES],
                           axis=1)
        if causal:  # rolling over time needs the rows in time order: sorted, then put back
            time_ns = out.loc[rows, "time_ns"].to_numpy(np.int64)
            order = np.argsort(time_ns, kind="stable")
            reference = np.empty_like(lengths)
            index, window = pd.DatetimeIndex(time_ns[order]), pd.Timedelta(seconds=window_s)
            reference[order] = pd.DataFrame(lengths[order], index=index).rolling(
                window, min_periods=1).median().to_numpy()
            deviation = np.abs(lengths - reference)
            spread = np.empty_like(lengths)
            spread[order] = pd.DataFrame(deviation[order], index=index).rolling(
                window, min_periods=1).median().to_numpy()
        else:
            reference = np.nanmedian(lengths, axis=0)
            deviation = np.abs(lengths - reference)
            spread = np.nanmedian(deviation, axis=0)
        tolerance = np.fmax(max_bone_error, BONE_NOISE_SIGMAS * 1.4826 * spread)
        with np.errstate(invalid="ignore"):
            off = deviation > tolerance
        bad = np.stack([off[:, [k for k, bone in enumerate(MODEL_BONES) if j in bone]].all(axis=1)
                        for j in range(len(MODEL_JOINT_IDS))], axis=1)  # (T, 8)
        bad_xyz = np.repeat(bad, 3, axis=1)
        out.loc[rows, JOINT_XYZ] = np.where(bad_xyz, np.nan, out.loc[rows, JOINT_XYZ].to_numpy(float))
        out.loc[rows, JOINT_VIEWS] = np.where(bad, 0, out.loc[rows, JOINT_VIEWS].to_numpy())
    return out


def filter_session(ball3d: pd.DataFrame, pose3d: pd.DataFrame, paddle: pd.DataFrame, cutoff_ball_hz: float,
                   cutoff_pose_hz: float, fs_hz: float = 100.0, hit_max_distance: float = 0.3,
                   paddle_fill_s: float = 0.25, max_bone_error: float = 0.10,
                   ) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """(ball_filtered, pose_filtered, events) of one session.

    Ball samples no neighbour confirms are dropped first (drop_ball_outliers). Events are found on the
    raw ball (a low-pass would round off the turns they are found by); the ball is then low-passed piece
    by piece between its hits and bounces, the pose joint by joint per player after clean_pose (bad
    joints become gaps, which stay NaN). The tables keep their columns (ball3d's and pose3d's), rows
    sorted by time (ball: one per frame).
    """
    ball3d = ball3d.sort_values("time_ns").reset_index(drop=True)
    if ball3d["time_ns"].duplicated().any():
        raise ValueError("ball3d: more than one row on a frame; expected one row per camera frame")
    ball3d = drop_ball_outliers(ball3d, fs_hz=fs_hz)
    events = detect_events(ball3d, paddle, hit_max_distance, paddle_fill_s, fs_hz)
    cuts = events.loc[events["kind"].isin(["hit", "bounce"]), "index"].to_numpy(int)
    ball = ball3d.copy()
    ball[["x", "y", "z"]] = lowpass_between_events(frame_seconds(ball3d["time_ns"]),
                                                   ball3d[["x", "y", "z"]].to_numpy(float), cuts,
                                                   cutoff_ball_hz, fs_hz)
    pose3d = clean_pose(pose3d, max_bone_error)
    parts = []
    for _, rows in pose3d.sort_values(["player", "time_ns"], kind="stable").groupby("player", sort=False):
        rows = rows.copy()
        rows[JOINT_XYZ] = lowpass(rows[JOINT_XYZ].to_numpy(float), cutoff_pose_hz, fs_hz)
        parts.append(rows)
    pose = pd.concat(parts).sort_values(["time_ns", "player"], kind="stable").reset_index(drop=True)
    return ball, pose[list(pose3d.columns)], events
