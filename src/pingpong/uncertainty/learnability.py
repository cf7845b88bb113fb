"""How far could any estimator fed the model's inputs rank the twin's strike-oracle std? A ceiling.

A small GRU (the anticipation stack with one output) is trained on the training hits with the oracle's own
log std as its target, the truth no estimator may see; its within-frame Spearman with the oracle std on the
test hits is what the inputs and this many hits allow. An estimator that must learn the std from single
draws of the model's error can do no better than this supervised net with the same inputs and hits: the
uncertainty verdict is read against it (issue 38's bar: the best estimator at >= 0.8 of it). The same net
trained on the model's own absolute errors (out of fold on the training hits: one draw per hit and frame,
what every estimator learns from) shows how much of the ceiling single draws leave within reach.
"""

import numpy as np
import pandas as pd
import torch

from pingpong.curation.schemas import HIT_KEYS
from pingpong.learning.adamw import AdamW
from pingpong.learning.models import AnticipationNet, prediction_frames

# (GRU width, epochs) tried; the one with the best calibration-hit Spearman is the ceiling on the test hits,
# so that the test hits choose nothing. On the default run of fb04da0 (98 test hits) the three gave 0.33,
# 0.39 and 0.42 on the test hits.
SETTINGS = ((16, 30), (32, 60), (64, 60))
N_BATCHES = 8  # minibatches an epoch


def oracle_matrix(dataset: pd.DataFrame, rows: pd.DataFrame) -> np.ndarray:
    """(hits, 31) oracle std of each dataset hit at t = -30 .. 0, NaN where no twin shot matched; rows:
    reports.uncertainty_oracle.join_test_hits' rows of every split."""
    at = dataset[HIT_KEYS].reset_index(drop=True).reset_index().merge(
        rows[[*HIT_KEYS, "frames_before_hit", "oracle_std_x"]])
    out = np.full((len(dataset), 31), np.nan)
    out[at["index"].to_numpy(), 30 - at["frames_before_hit"].to_numpy()] = at["oracle_std_x"].to_numpy()
    return out


def error_matrix(dataset: pd.DataFrame, predictions: pd.DataFrame) -> np.ndarray:
    """(hits, 31) the final model's absolute strike error (m) of each dataset hit at t = -30 .. 0 (the
    training hits' out of fold), NaN where it has none."""
    final = predictions[predictions["model"] == "final"]
    at = dataset[HIT_KEYS].reset_index(drop=True).reset_index().merge(
        final[[*HIT_KEYS, "frames_before_hit", "abs_error"]])
    out = np.full((len(dataset), 31), np.nan)
    out[at["index"].to_numpy(), 30 - at["frames_before_hit"].to_numpy()] = at["abs_error"].to_numpy()
    return out


def fit_on_oracle(X: np.ndarray, oracle_std: np.ndarray, rows: np.ndarray, hidden: int, epochs: int,
                  seed: int) -> np.ndarray:
    """(hits, 31) predicted log oracle std of a GRU trained (L1, AdamW) on `rows`' log oracle std; X (hits,
    frames, inputs), oracle_std (hits, 31) finite on `rows`."""
    net = AnticipationNet("gru", rnn_hidden=hidden, rnn_layers=1, mlp_hidden=hidden, mlp_layers=1,
                          dropout=0.2, velocity=True, n_output=1, seed=seed)
    x = torch.from_numpy(X)
    target = torch.from_numpy(np.log(np.where(rows[:, None], oracle_std, 1.0)).astype(np.float32))
    net.normaliser.fit(net.features(x[rows]))
    optimiser = AdamW(net.parameters(), lr=3e-3, weight_decay=1e-3)
    order = np.random.default_rng(seed)
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        net.train()
        for _ in range(epochs):
            for batch in np.array_split(order.permutation(np.flatnonzero(rows)), N_BATCHES):
                loss = (prediction_frames(net(x[batch]))[..., 0] - target[batch]).abs().mean()
                optimiser.zero_grad()
                loss.backward()
                optimiser.step()
    with torch.no_grad():
        return prediction_frames(net.eval()(x))[..., 0].numpy()
