"""Quantile heads for conformalised quantile regression: a small MLP trained with the pinball loss
to give the lower and upper quantiles of the strike-point residual y - y_hat from the frame features.

Cheap on a CPU: full-batch AdamW on (hits x 31) rows for a few hundred epochs.
"""

import numpy as np
import torch
from torch import nn

from pingpong.common.artifacts import Provenance, Schema, load_model, save_model
from pingpong.learning.adamw import AdamW
from pingpong.uncertainty.features import standardiser


class QuantileHeads(nn.Module):
    """Standardised features -> (N, 2) residual quantiles (m) at `levels`; mean/std are buffers."""

    def __init__(self, n_features: int, hidden: int, levels: tuple[float, float]):
        super().__init__()
        self.levels = levels
        self.register_buffer("mean", torch.zeros(n_features, dtype=torch.float64))
        self.register_buffer("std", torch.ones(n_features, dtype=torch.float64))
        self.net = nn.Sequential(nn.Linear(n_features, hidden), nn.ReLU(), nn.Linear(hidden, hidden),
                                 nn.ReLU(), nn.Linear(hidden, 2))

    def forward(self, features: torch.Tensor) -> torch.Tensor:
        return self.net(((features - self.mean) / self.std).float())


def pinball_loss(pred: torch.Tensor, target: torch.Tensor, levels) -> torch.Tensor:
    """Mean pinball (quantile) loss of pred (N, Q) at quantile `levels` (Q,) for target (N,)."""
    tau = torch.as_tensor(levels, dtype=pred.dtype)
    diff = target[:, None] - pred
    return torch.maximum(tau * diff, (tau - 1) * diff).mean()


def fit_quantile_heads(features: np.ndarray, residuals: np.ndarray, levels: tuple[float, float],
                       rng: np.random.Generator, *, hidden: int = 32, epochs: int = 300,
                       lr: float = 0.01, weight_decay: float = 1e-3) -> QuantileHeads:
    """Train the heads on (features, residual = y - y_hat) rows; weights seeded from `rng`."""
    features = np.asarray(features, float)
    heads = QuantileHeads(features.shape[1], hidden, levels)
    mean, std = standardiser(features)
    heads.mean.copy_(torch.from_numpy(mean))
    heads.std.copy_(torch.from_numpy(std))
    x = torch.from_numpy(features)
    y = torch.as_tensor(residuals, dtype=torch.float32)
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(int(rng.integers(2**31)))
        heads.net.apply(lambda m: m.reset_parameters() if isinstance(m, nn.Linear) else None)
    optimiser = AdamW(heads.parameters(), lr=lr, weight_decay=weight_decay)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # the net is tiny: more threads only add waiting (30x slower on a busy CPU)
    try:
        for _ in range(epochs):  # no dropout or shuffling: the only randomness is the initial weights
            loss = pinball_loss(heads(x), y, levels)
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
    finally:
        torch.set_num_threads(threads)
    return heads.eval()


@torch.no_grad()
def predict_quantiles(heads: QuantileHeads, features: np.ndarray) -> np.ndarray:
    """(N, 2) lower <= upper residual quantiles (m); sorted, since two heads may cross."""
    return np.sort(heads(torch.as_tensor(np.asarray(features, float))).double().numpy(), axis=1)


HEADS_SCHEMA = Schema("quantile_heads", 1)


def save(heads: QuantileHeads, stem, prov: Provenance) -> None:
    hparams = {"n_features": heads.mean.numel(), "hidden": heads.net[0].out_features,
               "levels": list(heads.levels)}
    save_model(heads.state_dict(), hparams, stem, HEADS_SCHEMA, prov)


def load(stem) -> QuantileHeads:
    tensors, hparams = load_model(stem, HEADS_SCHEMA)
    heads = QuantileHeads(hparams["n_features"], hparams["hidden"], tuple(hparams["levels"]))
    heads.load_state_dict(tensors)
    return heads.eval()
