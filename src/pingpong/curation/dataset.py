"""The dataset of kept hits: model input sequences, labels, strike points, regions and splits.

Layout (one row per kept hit): 'x' holds the input sequence as a flat list of n_frames * 39 float32,
row-major (frame, value): frame k is t = k - (n_frames - 1) frames, so the last frame is the hit (t = 0),
and the 39 values are those of docs/architecture.md (8 hitter joints, hitter's paddle position and
rotation, ball), all mirrored so that the hit travels towards -y. `dataset_arrays` reads it back into
X (N, T, 39).

Inputs come in two kinds (config curation.inputs):
- causal (the default): the input at frame t depends on measurements up to t only, as on a live robot.
  The tables are the cleaned but unfiltered measurements (the filtering rule's interim/causal/, cleaned
  with past-only checks); each player's 39 values are low-passed forwards only over the whole session
  (curation.causal.causal_lowpass, per channel: the joints at curation.causal_cutoff_pose_hz, the ball
  at causal_cutoff_ball_hz or not at all, the paddle not at all), holding the last value through a
  dropout, before the windows are cut. learning.streaming.StreamingPredictor runs the same filter frame
  by frame.
- zero_phase: the filtering rule's zero-phase tables (interim/filtered/), whose every sample also
  carries later measurements (the paper's offline setting; kept for comparison).

Gaps: where curation allowed them (at most its max_*_frames per window), a missing value is the last
value seen before it in the session (forward fill: causal, what a streaming predictor holds too); a
value missing from the window's first frames on with nothing seen before it in the session takes the
window's first seen value (the one non-causal fill; it needs a recording that starts inside the window).
So X is finite;
n_filled_frames counts the frames of a hit where any measurement was missing.
"""

import numpy as np
import pandas as pd

from pingpong.curation.causal import causal_lowpass
from pingpong.curation.labels import mirror_frames
from pingpong.curation.schemas import DATASET
from pingpong.curation.splits import split_by_rally
from pingpong.curation.tracks import JOINT_XYZ, PLAYER_END, paddle_arrays, per_player
from pingpong.frames import N_INPUT, N_JOINT_VALUES

INPUT_KINDS = ("causal", "zero_phase")


def _forward_fill(values: np.ndarray) -> np.ndarray:
    """Columns of values (T, D) with each NaN replaced by the last finite value above it (NaN before)."""
    return pd.DataFrame(values).ffill().to_numpy(float)


def _back_fill(values: np.ndarray) -> np.ndarray:
    """Columns of values (T, D) whose leading NaNs take the first finite value below them."""
    return pd.DataFrame(values).bfill().to_numpy(float)


def causal_input_cutoffs(cutoff_pose_hz: float, cutoff_ball_hz: float | None) -> list[float | None]:
    """Per input channel (39) the causal low-pass cut-off (Hz; None: not filtered): joints, paddle, ball."""
    return [cutoff_pose_hz] * N_JOINT_VALUES + [None] * 12 + [cutoff_ball_hz] * 3


def player_frames(ball: pd.DataFrame, pose: pd.DataFrame, paddle: pd.DataFrame, player: str) -> np.ndarray:
    """A player's 39 input values (T, 39) on the ball table's frames, unmirrored; NaN where unmeasured."""
    time_ns = ball["time_ns"].to_numpy(np.int64)
    return np.hstack([per_player(pose, player, JOINT_XYZ, time_ns), paddle_arrays(paddle, player, time_ns),
                      ball[["x", "y", "z"]].to_numpy(float)])


def input_sequences(segments: pd.DataFrame, ball: pd.DataFrame, pose: pd.DataFrame, paddle: pd.DataFrame,
                    n_frames: int = 40, causal_cutoffs: list | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(X (N, n_frames, 39) float32, n_filled_frames (N,)) of one session's candidates (segments rows).

    ball, pose: the session's ball and pose tables on the ball's frames (zero-phase filtered, or cleaned
    raw with causal_cutoffs: causal_input_cutoffs, module docstring); paddle: the paddle table. Each
    sequence is the hitter's frames hit_frame - n_frames + 1 .. hit_frame, mirrored for a 'far' hitter
    and gap-filled (module docstring). Raises ValueError if a value is missing from a whole window
    (curation should have rejected that hit) or the window starts before the recording.
    """
    measured = {p: player_frames(ball, pose, paddle, p) for p in PLAYER_END}
    per_frame = {p: _forward_fill(v if causal_cutoffs is None else causal_lowpass(v, causal_cutoffs))
                 for p, v in measured.items()}
    X = np.empty((len(segments), n_frames, N_INPUT))
    n_filled = np.zeros(len(segments), int)
    for k, seg in enumerate(segments.itertuples(index=False)):
        first = seg.hit_frame - n_frames + 1
        if first < 0:
            raise ValueError(f"session {seg.session} hit {seg.hit}: {n_frames} frames before the hit start "
                             "before the recording")
        window = slice(first, seg.hit_frame + 1)
        n_filled[k] = int((~np.isfinite(measured[seg.hitter][window]).all(axis=1)).sum())
        filled = _back_fill(per_frame[seg.hitter][window])
        if not np.isfinite(filled).all():
            raise ValueError(f"session {seg.session} hit {seg.hit}: an input value is missing from all "
                             f"{n_frames} frames before the hit; curation should have excluded it")
        X[k] = filled if seg.hitter == "near" else mirror_frames(filled)
    return X.astype(np.float32), n_filled


def build_dataset(segments: pd.DataFrame, sessions: dict, rng: np.random.Generator, n_frames: int = 40,
                  test_fraction: float = 0.2, calibration_fraction: float = 0.1,
                  n_folds: int = 5, causal_cutoffs: list | None = None) -> pd.DataFrame:
    """DATASET table of the kept hits of all sessions.

    segments: curated candidates of every session (curate_segments, 'session' column); sessions: session
    name -> (ball, pose, paddle), the ball and pose tables of the inputs' kind and the paddle table of
    that session (causal_cutoffs: input_sequences); rng: draws the rally order of split_by_rally
    ('split' train / calibration / test, 'fold' 0..n_folds-1 within train, -1 elsewhere; a rally lies
    wholly in one part and one fold).
    """
    if n_frames < 31:
        raise ValueError(f"n_frames {n_frames}: the model predicts from 30 frames before the hit, so an "
                         "input sequence needs at least 31 frames")
    parts = []
    for session, kept in segments[segments["decision"] == "kept"].groupby("session", sort=True):
        if session not in sessions:
            raise ValueError(f"segments of session '{session}' but no filtered tables for it")
        kept = kept.sort_values("hit_frame")
        X, n_filled = input_sequences(kept, *sessions[session], n_frames, causal_cutoffs)
        parts.append(kept.assign(n_frames=n_frames, x=list(X.reshape(len(X), -1)), n_filled_frames=n_filled))
    columns = [c for c in DATASET.columns if c not in ("split", "fold")]
    if not parts:
        raise ValueError("no kept hits in any session: nothing to build a dataset of")
    dataset = pd.concat(parts, ignore_index=True)[columns]
    return split_by_rally(dataset, rng, test_fraction, calibration_fraction, n_folds)
