"""Per-(hit, frame) features of what the model had seen when it predicted: for the k-NN error
regressor and the quantile heads."""

import numpy as np

FRAME_HZ = 100.0  # camera clock


def frame_features(X: np.ndarray, frames_before_hit: np.ndarray) -> np.ndarray:
    """(N * len(frames_before_hit), 2 * 39 + 1): for hit n and each frame f before its hit (row
    n * K + j is frames_before_hit[j]) the inputs at t = -f, their rates of change (per s, from the
    frame before) and f itself. X: (N, T, 39), the last frame is the hit."""
    X = np.asarray(X, dtype=float)
    idx = X.shape[1] - 1 - np.asarray(frames_before_hit)
    if idx.min() < 1:
        raise ValueError(f"frame_features: {X.shape[1]} input frames cannot give frame {idx.min()} "
                         "and the one before it")
    now, before = X[:, idx], X[:, idx - 1]
    f = np.broadcast_to(np.asarray(frames_before_hit, float)[None, :, None], (*now.shape[:2], 1))
    return np.concatenate([now, (now - before) * FRAME_HZ, f], axis=-1).reshape(-1, 2 * X.shape[2] + 1)


def standardiser(features: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(mean, std) per column of the fitting rows; a constant column keeps std 1."""
    std = features.std(axis=0)
    return features.mean(axis=0), np.where(std > 1e-9, std, 1.0)

