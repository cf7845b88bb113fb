"""Cross-validated training of the anticipation models, the refit of the winner, and its predictions.

One call of `fit_fold` is one (configuration, fold) job of the grid; `refit` trains the winner on the
whole training part for the median number of epochs its folds stopped at (no validation data is
left to stop on); `prediction_table` lays predictions out one row per (hit, frame before the hit).
"""

from dataclasses import asdict, dataclass, replace

import numpy as np
import pandas as pd

from pingpong.common.config import Settings
from pingpong.frames import N_INPUT
from pingpong.learning.models import FRAMES_BEFORE_HIT, AnticipationNet
from pingpong.learning.train import evaluate_loss, strike_points, train

ARCHITECTURE_KEYS = ("cell", "rnn_hidden", "rnn_layers", "mlp_hidden", "mlp_layers", "dropout")
BALL_ONLY = slice(N_INPUT - 3, N_INPUT)  # the last 3 of the 39 values are the ball


@dataclass(frozen=True)
class TrainSettings(Settings):
    """How every job of the learning stages trains (config training.*, and the device)."""

    batch_size: int
    max_epochs: int
    patience: int
    min_delta: float
    early_frame_weight: float
    reflect_augment: bool
    device: str


def make_net(config: dict, seed: int, n_input: int = N_INPUT) -> AnticipationNet:
    cfg = {k: config[k] for k in ARCHITECTURE_KEYS}
    # velocity inputs go beyond the paper; configurations without the key are the paper's nets
    return AnticipationNet(cfg.pop("cell"), n_input=n_input, seed=seed,
                           velocity=bool(config.get("velocity", False)), **cfg)


def fit_fold(X: np.ndarray, Y: np.ndarray, folds: np.ndarray, fold: int, config: dict,
             settings: TrainSettings, seed: int) -> tuple[AnticipationNet, dict]:
    """Train `config` on the training folds but `fold`, validate on `fold`; the net and a summary."""
    val = folds == fold
    net = make_net(config, seed, X.shape[-1])
    _, history = train(net, X[~val], Y[~val], X[val], Y[val], config["lr"], seed=seed, **asdict(settings))
    best = min(history, key=lambda h: h["val_loss"])
    return net, {"config_id": config["config_id"], "fold": fold,
                 "val_loss": evaluate_loss(net, X[val], Y[val]), "best_epoch": best["epoch"],
                 "epochs_run": len(history)}


def refit(X: np.ndarray, Y: np.ndarray, config: dict, epochs: int, settings: TrainSettings,
          seed: int) -> AnticipationNet:
    """The winner trained on all of X for `epochs` epochs (the training loss picks the kept weights)."""
    net = make_net(config, seed, X.shape[-1])
    fixed = replace(settings, max_epochs=epochs, patience=epochs + 1)
    train(net, X, Y, X, Y, config["lr"], seed=seed, **asdict(fixed))
    return net


def prediction_table(dataset: pd.DataFrame, pred: np.ndarray, model: str) -> pd.DataFrame:
    """One row per (hit, frame before the hit): predicted a1, a2, b, strike x, and the measured strike."""
    n, k = pred.shape[:2]
    strike = strike_points(pred)
    rep = np.repeat(np.arange(n), k)
    columns = ["session", "rally", "hit", "split", "fold", "strike_x", "region"]
    table = dataset.iloc[rep][columns].reset_index(drop=True)
    table.insert(0, "model", model)
    table["frames_before_hit"] = np.tile(FRAMES_BEFORE_HIT, n)
    table[["a1", "a2", "b"]] = pred.reshape(-1, 3)
    table["strike_x_pred"] = strike.reshape(-1)
    table["abs_error"] = np.abs(table["strike_x_pred"] - table["strike_x"])
    return table
