"""Causal model inputs: the ball and pose cleaned and low-passed using past measurements only, so that
the value at frame t depends on the frames up to t, as a live robot computes it.

filter_session's zero-phase filter puts measurements from after t into the value at t (the
follow-through leaks into the frames before a hit). Here a Butterworth low-pass runs forwards only
(causal_lowpass in batch, CausalLowpass one frame at a time, same numbers), the ball gate and the
pose check look back only (drop_ball_outliers and clean_pose with causal=True), and
causal_session_inputs builds filter_session's ball and pose tables that way.

NaN policy, the same in batch and streaming: before a channel's first finite sample the output is NaN;
from then on a NaN input is held at the last finite input inside the filter (what a tracker holds
through a dropout), but the output on that frame is NaN, so gaps stay gaps and the dataset's gap
accounting and forward fill (dataset.py) work as on the offline tables. A live consumer forward-fills
the output the same way. Samples are taken as uniform at fs_hz (row k at k / fs_hz).

The forward filter lags: a ramp comes out ~1 / (2 pi cutoff) s late at order 1, ~sqrt(2) / (2 pi cutoff)
at order 2 (10 and 14 ms at 15 Hz), and it runs through hits and bounces (known only later), which
the offline filter cuts at. A ball at 5-10 m/s pays more for that lag than the ~2 mm of noise a
low-pass removes, hence cutoff None (no low-pass) for the ball.
"""

from functools import lru_cache

import numpy as np
import pandas as pd
from scipy.signal import butter, sosfilt, sosfilt_zi

from pingpong.curation.events import drop_ball_outliers
from pingpong.curation.filtering import clean_pose
from pingpong.curation.tracks import JOINT_XYZ

BALL_XYZ = ["x", "y", "z"]


@lru_cache(maxsize=64)
def _design(cutoff_hz: float, fs_hz: float, order: int) -> tuple[np.ndarray, np.ndarray]:
    """(sos, zi): Butterworth sections and their unit steady state (n_sections, 2)."""
    if not 0 < cutoff_hz < fs_hz / 2:
        raise ValueError(f"cutoff {cutoff_hz} Hz must lie in (0, {fs_hz / 2}) Hz (Nyquist at fs {fs_hz} Hz)")
    sos = butter(order, cutoff_hz, fs=fs_hz, output="sos")
    return sos, sosfilt_zi(sos)


def _groups(cutoff_hz, n_channels: int) -> dict:
    """Channel indices by cutoff (Hz or None: unfiltered) from one value or one per channel."""
    cutoffs = [cutoff_hz] * n_channels if cutoff_hz is None or np.isscalar(cutoff_hz) else list(cutoff_hz)
    if len(cutoffs) != n_channels:
        raise ValueError(f"{len(cutoffs)} cutoffs for {n_channels} channels")
    groups: dict = {}
    for k, c in enumerate(cutoffs):
        groups.setdefault(None if c is None else float(c), []).append(k)
    return {c: np.array(cols) for c, cols in groups.items()}


def _held(values: np.ndarray, finite: np.ndarray) -> np.ndarray:
    """Columns of values (T, D) with each NaN replaced by the last finite value above it (NaN before)."""
    last = np.maximum.accumulate(np.where(finite, np.arange(len(values))[:, None], 0), axis=0)
    return np.take_along_axis(values, last, axis=0)


def causal_lowpass(values, cutoff_hz, fs_hz: float = 100.0, order: int = 1) -> np.ndarray:
    """Uniformly sampled values (T, D) or (T,) low-passed forwards only, column by column.

    cutoff_hz: the Butterworth -3 dB frequency, one value or one per column; None leaves a column
    unfiltered. Each column's filter starts at steady state on its first finite value (a constant passes
    unchanged) and runs on the held signal (NaN inputs held at the last finite one); the output is NaN
    where the input is NaN (module docstring). Row t equals CausalLowpass.step(row t) after rows 0..t-1.
    Columns sharing a cutoff and a first finite row are filtered in one sosfilt call.
    """
    x = np.asarray(values, dtype=float)
    flat = x.reshape(len(x), int(np.prod(x.shape[1:])))
    if len(flat) == 0:
        return x.copy()
    finite = np.isfinite(flat)
    held = _held(flat, finite)
    first = np.where(finite.any(axis=0), finite.argmax(axis=0), len(flat))
    out = flat.copy()
    for cutoff, cols in _groups(cutoff_hz, flat.shape[1]).items():
        if cutoff is None:
            continue
        sos, zi = _design(cutoff, float(fs_hz), int(order))
        for start in np.unique(first[cols][first[cols] < len(flat)]):
            c = cols[first[cols] == start]
            out[start:, c] = sosfilt(sos, held[start:, c], axis=0, zi=zi[:, :, None] * held[start, c])[0]
    out[~finite] = np.nan
    return out.reshape(x.shape)


class CausalLowpass:
    """causal_lowpass one frame at a time: step(frame) after frames 0..t-1 returns causal_lowpass's row t
    of the same sequence (within ~1e-15), NaN policy included; reset() starts again.

    n_channels: D; cutoff_hz: one value or one per channel, None for unfiltered (only NaN-where-NaN).
    """

    def __init__(self, n_channels: int, cutoff_hz, fs_hz: float = 100.0, order: int = 1):
        self.n_channels = int(n_channels)
        self._filters = [(cols, *_design(c, float(fs_hz), int(order)))
                         for c, cols in _groups(cutoff_hz, self.n_channels).items() if c is not None]
        self.reset()

    def reset(self) -> None:
        """Forget all frames: every channel waits for its first finite sample again."""
        self._held = np.full(self.n_channels, np.nan)
        self._states = [np.zeros((len(sos), 2, len(cols))) for cols, sos, _ in self._filters]

    def step(self, frame) -> np.ndarray:
        """The filtered frame (D,) of the next input frame (D,), NaN where the input is NaN."""
        x = np.asarray(frame, dtype=float).reshape(-1)
        if len(x) != self.n_channels:
            raise ValueError(f"frame of {len(x)} values for {self.n_channels} channels")
        finite = np.isfinite(x)
        starting = finite & np.isnan(self._held)
        self._held = np.where(finite, x, self._held)
        out = x.copy()
        for (cols, sos, zi), state in zip(self._filters, self._states, strict=True):
            new = starting[cols]
            state[:, :, new] = zi[:, :, None] * self._held[cols[new]]
            # a channel not started yet runs on NaN; its state is set when its first sample comes
            y, state[...] = sosfilt(sos, self._held[cols][None], axis=0, zi=state)
            out[cols] = y[0]
        out[~finite] = np.nan
        return out


def causal_session_inputs(ball3d: pd.DataFrame, pose3d: pd.DataFrame, cutoff_ball_hz, cutoff_pose_hz,
                          fs_hz: float = 100.0, max_bone_error: float = 0.10,
                          order: int = 1) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(ball, pose) of one session as filter_session makes them (same columns; ball one row per frame in
    time order, pose rows sorted by (time_ns, player)), but causal: a row depends on rows up to its time.

    The ball: unconfirmed samples dropped by the past-only gate (drop_ball_outliers, causal=True), then
    causal_lowpass over the whole track (no event cuts: events are only known later). The pose: bad joints
    removed by the trailing-median check (clean_pose, causal=True), then causal_lowpass per player, rows
    as uniform frames. Cutoffs in Hz; None: not low-passed. Missing samples stay NaN (module docstring).
    """
    ball = ball3d.sort_values("time_ns").reset_index(drop=True)
    if ball["time_ns"].duplicated().any():
        raise ValueError("ball3d: more than one row on a frame; expected one row per camera frame")
    ball = drop_ball_outliers(ball, fs_hz=fs_hz, causal=True)
    ball[BALL_XYZ] = causal_lowpass(ball[BALL_XYZ].to_numpy(float), cutoff_ball_hz, fs_hz, order)
    pose = clean_pose(pose3d, max_bone_error, causal=True)
    parts = []
    for _, rows in pose.sort_values(["player", "time_ns"], kind="stable").groupby("player", sort=False):
        rows = rows.copy()
        rows[JOINT_XYZ] = causal_lowpass(rows[JOINT_XYZ].to_numpy(float), cutoff_pose_hz, fs_hz, order)
        parts.append(rows)
    if parts:
        pose = pd.concat(parts)
    pose = pose.sort_values(["time_ns", "player"], kind="stable").reset_index(drop=True)
    return ball, pose[list(pose3d.columns)]
