"""How much of the strike point the inputs carry, against what the configured net learns from them.

Out-of-fold median strike-point errors on the training hits of processed/dataset.parquet (the dataset's own
5 folds), at 30, 20, 10, 5, 1 and 0 frames before the hit, for
- the selected configuration (processed/models/selection.json), trained with config/config.yaml's
  training settings (batch size, early stopping, early-frame weight, reflection), over several seeds, each
  seed alone and their average; `--set KEY=VALUE` changes an architecture key or a setting (e.g. `--set
  reflect_augment=false`, the default before this key; `--set rnn_layers=2 rnn_hidden=32
  early_frame_weight=1 reflect_augment=false`, before de4fc9f);
- a ridge probe fitted per frame on that frame's 39 inputs, their change over 1 and 3 frames, and the same
  again times the stroke side (forehand +1, backhand -1: the sign of the paddle face's y), standardised.
Run from the repository root after the select_model rule:
`.venv/bin/python analysis/learning_probe.py [--seeds N] [--set KEY=VALUE ...]`.
"""

import argparse
import json

import numpy as np
import torch
import yaml

from pingpong.common.artifacts import read_table
from pingpong.common.config import validate_config
from pingpong.curation.schemas import DATASET, dataset_arrays
from pingpong.learning.cv import make_net
from pingpong.learning.train import predict, strike_points, train

FRAMES_SHOWN = (30, 20, 10, 5, 1, 0)
PADDLE_FACE_Y = 24 + 3 + 5  # r12 of the paddle's rotation: its face normal's y (mirrored table frame)


def ridge_per_frame(X, strike, train_rows, lam=10.0) -> np.ndarray:
    """(rows not in train_rows, 31) ridge predictions, one fit per prediction frame."""
    out = []
    for i in range(X.shape[1] - 31, X.shape[1]):
        f = np.concatenate([X[:, i], X[:, i] - X[:, i - 1], X[:, i] - X[:, i - 3]], axis=1)
        side = np.sign(-X[:, i, PADDLE_FACE_Y])[:, None]
        f = np.concatenate([f, side * f, side], axis=1)
        f = (f - f[train_rows].mean(0)) / (f[train_rows].std(0) + 1e-9)
        f = np.concatenate([f, np.ones((len(f), 1))], axis=1)
        a = f[train_rows]
        w = np.linalg.solve(a.T @ a + lam * np.eye(a.shape[1]), a.T @ strike[train_rows])
        out.append(f[~train_rows] @ w)
    return np.stack(out, axis=1)


SETTING_KEYS = ("batch_size", "max_epochs", "patience", "min_delta", "early_frame_weight", "reflect_augment")


def main(seeds: int, overrides: list[str]) -> None:
    torch.set_num_threads(1)
    config = validate_config(yaml.safe_load(open("config/config.yaml")), "config/schema.yaml")
    settings = {k: config["training"][k] for k in SETTING_KEYS}
    cell = json.loads(open("processed/models/selection.json").read())["config"]
    for item in overrides:
        key, value = item.split("=")
        (settings if key in SETTING_KEYS else cell)[key] = yaml.safe_load(value)
    print("net:", {k: v for k, v in cell.items() if k != "config_id"}, "training:", settings)
    dataset = read_table("processed/dataset.parquet", DATASET)
    train_part = dataset[dataset["split"] == "train"]
    X, Y = dataset_arrays(train_part)
    folds = train_part["fold"].to_numpy()
    strike = (Y[:, 1] * -1.40 + Y[:, 2]).astype(float)
    preds = {name: np.zeros((len(X), 31)) for name in ["ridge", *(f"net seed {s}" for s in range(seeds))]}
    epochs = []
    for fold in np.unique(folds):
        val = folds == fold
        preds["ridge"][val] = ridge_per_frame(X, strike, ~val)
        for seed in range(seeds):
            net = make_net(cell, seed)
            _, history = train(net, X[~val], Y[~val], X[val], Y[val], cell["lr"], seed=seed, device="cpu",
                               progress=False, **settings)
            epochs.append(len(history))
            preds[f"net seed {seed}"][val] = strike_points(predict(net, X[val]))
    print(f"epochs run per fit: mean {np.mean(epochs):.1f}, {sum(epochs)} in all")
    preds["net, seeds averaged"] = np.mean([preds[f"net seed {s}"] for s in range(seeds)], axis=0)
    print(f"{len(X)} training hits, out of fold; median |strike error| cm at frames {FRAMES_SHOWN}; "
          f"the training mean: {100 * np.median(np.abs(strike - strike.mean())):.1f} cm")
    for name, p in preds.items():
        med = 100 * np.median(np.abs(p - strike[:, None]), axis=0)
        cols = " ".join(f"{med[30 - f]:5.1f}" for f in FRAMES_SHOWN)
        print(f"{name:22s} {cols}   1/10 frames: {med[29] / med[20]:.2f}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE")
    args = parser.parse_args()
    main(args.seeds, args.set)
