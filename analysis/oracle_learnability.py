"""How far could any estimator fed the inputs rank the twin's strike-oracle std? A diagnostic ceiling.

A small GRU (the anticipation stack with one output) is trained on the training hits with the oracle's own
log std as its target, the truth no estimator may see, and its within-frame Spearman with the oracle std is
measured on the calibration and test hits (mean over frames 1-20 before the hit, the uncertainty issue's bar
0.6). An estimator that must learn the std from single residual draws of the model's error can do no better
than this supervised net with the same inputs and hits. Twin runs only; run from the repository root after
the predict rule: `.venv/bin/python analysis/oracle_learnability.py`.
"""

import numpy as np
import pandas as pd
import torch

from pingpong.common.artifacts import read_table
from pingpong.curation.schemas import DATASET, HIT_KEYS, dataset_arrays
from pingpong.learning.models import AnticipationNet, prediction_frames
from pingpong.learning.schemas import PREDICTIONS
from pingpong.reports.uncertainty import ORACLE_FRAMES
from pingpong.reports.uncertainty_oracle import join_test_hits, read_oracles
from pingpong.uncertainty.metrics import spearman, within_frames

SETTINGS = ((16, 30), (32, 60), (64, 60))  # (GRU width, epochs)


def oracle_matrix(dataset: pd.DataFrame) -> np.ndarray:
    """(hits, 31) oracle std of every dataset hit at t = -30 .. 0 (NaN where no twin shot matched)."""
    predictions = read_table("processed/predictions.parquet", PREDICTIONS)
    sessions = sorted(dataset["session"].unique())
    oracles = read_oracles(sessions, [f"raw/twin_truth/{s}/strike_oracle.parquet" for s in sessions])
    rows = join_test_hits(dataset, predictions, oracles, splits=("train", "calibration", "test"))
    at = dataset[HIT_KEYS].reset_index().merge(rows[[*HIT_KEYS, "frames_before_hit", "oracle_std_x"]])
    out = np.full((len(dataset), 31), np.nan)
    out[at["index"].to_numpy(), 30 - at["frames_before_hit"].to_numpy()] = at["oracle_std_x"].to_numpy()
    return out


def fit_on_oracle(X: np.ndarray, target: np.ndarray, rows: np.ndarray, hidden: int,
                  epochs: int) -> np.ndarray:
    """(hits, 31) predicted log oracle std of a GRU trained (L1) on `rows`' log oracle std."""
    net = AnticipationNet("gru", rnn_hidden=hidden, rnn_layers=1, mlp_hidden=hidden, mlp_layers=1,
                          dropout=0.2, velocity=True, n_output=1, seed=0)
    x, t = torch.from_numpy(X), torch.from_numpy(np.log(target).astype(np.float32))
    net.normaliser.fit(net.features(x[rows]))
    optimiser = torch.optim.AdamW(net.parameters(), lr=3e-3, weight_decay=1e-3)
    order = np.random.default_rng(0)
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(0)
        net.train()
        for _ in range(epochs):
            for batch in np.array_split(order.permutation(np.flatnonzero(rows)), 8):
                loss = (prediction_frames(net(x[batch]))[..., 0] - t[batch]).abs().mean()
                optimiser.zero_grad()
                loss.backward()
                optimiser.step()
    with torch.no_grad():
        return prediction_frames(net.eval()(x))[..., 0].numpy()


def main() -> None:
    torch.set_num_threads(1)
    dataset = read_table("processed/dataset.parquet", DATASET)
    X, _ = dataset_arrays(dataset)
    oracle = oracle_matrix(dataset)
    matched = np.isfinite(oracle).all(axis=1)
    split = dataset["split"].to_numpy()
    columns = 30 - np.asarray(ORACLE_FRAMES)
    frames = np.tile(np.asarray(ORACLE_FRAMES), len(X))
    for hidden, epochs in SETTINGS:
        u = fit_on_oracle(X, np.nan_to_num(oracle, nan=1.0), matched & (split == "train"), hidden, epochs)
        for part in ("calibration", "test"):
            m = matched & (split == part)
            rho = within_frames(spearman, u[m][:, columns].ravel(), oracle[m][:, columns].ravel(),
                                frames[: m.sum() * len(columns)])
            print(f"GRU {hidden} x {epochs} epochs trained on the oracle std, {part} hits ({m.sum()}): "
                  f"within-frame Spearman with it over frames 1-20 = {rho:.3f}")


if __name__ == "__main__":
    main()
