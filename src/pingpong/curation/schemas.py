"""The curation stages' table layouts and the dataset's reader (light: no stage code and no SciPy, so
readers, the training jobs among them, neither hash the stages nor pay their imports)."""

import numpy as np
import pandas as pd

from pingpong.common.artifacts import Schema
from pingpong.frames import N_INPUT

EVENT_COLUMNS = ("kind", "index", "time_ns", "player", "side", "x", "y", "z")
EVENTS = Schema("ball_events", 1, EVENT_COLUMNS)
CURATION_RULES = ("net", "out", "double_bounce", "no_strike_line", "few_points", "no_incoming",
                  "short_history", "ball_gaps", "pose_gaps", "paddle_gaps")
CANDIDATE_COLUMNS = (  # find_segments
    "session", "hit", "hitter", "t_hit_ns", "hit_frame", "start_frame", "end_frame", "flight_end_frame",
    "post_bounce_sides", "n_opponent_bounces", "crosses_net", "reaches_strike_line", "n_path_points")
SEGMENTS = Schema("segments", 1, (  # curate_segments
    *CANDIDATE_COLUMNS, "rally", "ball_missing_frames", "joint_missing_frames", "paddle_missing_frames",
    "a1", "a2", "b", "strike_x", "strike_z", "strike_x_labels", "region", "decision", "reasons"))
HIT_KEYS = ["session", "rally", "hit"]  # what names a hit in the dataset and every table after it
DATASET = Schema("dataset", 1, (
    *HIT_KEYS, "hitter", "t_hit_ns", "hit_frame", "n_frames", "x", "n_filled_frames",
    "a1", "a2", "b", "strike_x", "strike_z", "strike_x_labels", "region", "split", "fold"))


def dataset_arrays(dataset: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """(X (N, T, 39) float32, Y (N, 3) float32 labels a1, a2, b) of a DATASET table."""
    n_frames = dataset["n_frames"].unique()
    if len(n_frames) != 1:
        raise ValueError(f"dataset mixes sequence lengths {sorted(n_frames)}")
    X = np.stack(dataset["x"].to_numpy()).astype(np.float32).reshape(len(dataset), int(n_frames[0]), N_INPUT)
    return X, dataset[["a1", "a2", "b"]].to_numpy(np.float32)
