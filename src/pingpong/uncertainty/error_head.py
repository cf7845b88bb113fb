"""A learned error head: a small recurrent net that reads a hit's input frames and the final model's
strike-point prediction, and predicts the size of that prediction's error at each of the 31 prediction frames.

The issue's third difficulty estimate for normalised conformal, beside the ensemble spread and the
k-NN error. It reuses the anticipation stack (AnticipationNet with one output) on the 39 inputs plus
one channel, the final model's predicted strike x (0 before the prediction frames), and learns
log(|error| + ERROR_FLOOR) with an L1 loss (the median of the log error: robust to the heavy tail)
from the training hits' out-of-fold errors, so its targets are errors on hits the model had not seen.
"""

import numpy as np
import torch

from pingpong.common.artifacts import Provenance, Schema, load_model, save_model
from pingpong.frames import N_INPUT, N_PRED_FRAMES
from pingpong.learning.adamw import AdamW
from pingpong.learning.models import AnticipationNet, prediction_frames

ERROR_FLOOR = 0.02  # m: errors below 2 cm count as 2 cm (the log of a near-zero error is noise)
N_BATCHES = 6  # minibatches of hits per epoch
HEAD_SCHEMA = Schema("error_head", 1)


def head_inputs(X: np.ndarray, strike_pred: np.ndarray) -> torch.Tensor:
    """(N, T, 40): X (N, T, 39) with the predicted strike x (N, 31) on the 31 prediction frames."""
    X = np.asarray(X, np.float32)
    channel = np.zeros((*X.shape[:2], 1), np.float32)
    channel[:, -1 - N_PRED_FRAMES:, 0] = strike_pred
    return torch.from_numpy(np.concatenate([X, channel], axis=-1))


def train_head(X: np.ndarray, strike_pred: np.ndarray, n_output: int, loss_of, rng: np.random.Generator, *,
               hidden: int, epochs: int, lr: float = 3e-3, dropout: float = 0.2,
               weight_decay: float = 1e-3) -> AnticipationNet:
    """A head on the anticipation stack (one GRU layer, velocity inputs, `n_output` outputs per frame) read
    from head_inputs(X, strike_pred), trained with AdamW on N_BATCHES minibatches of hits per epoch to
    minimise loss_of(outputs (B, 31, n_output) at the prediction frames, the batch's hit indices);
    seeded from rng (weights, minibatch order, dropout masks), torch's global stream left as it was."""
    seed = int(rng.integers(2**31))
    net = AnticipationNet("gru", n_input=N_INPUT + 1, rnn_hidden=hidden, rnn_layers=1, mlp_hidden=hidden,
                          mlp_layers=1, dropout=dropout, velocity=True, n_output=n_output, seed=seed)
    x = head_inputs(X, strike_pred)
    net.normaliser.fit(net.features(x))
    optimiser = AdamW(net.parameters(), lr=lr, weight_decay=weight_decay)
    shuffle = np.random.default_rng(seed)  # minibatch order
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)  # dropout masks
        net.train()
        for _ in range(epochs):
            for batch in np.array_split(shuffle.permutation(len(x)), min(N_BATCHES, len(x))):
                loss = loss_of(prediction_frames(net(x[batch])), batch)
                optimiser.zero_grad()
                loss.backward()
                optimiser.step()
    return net.eval()


def fit_error_head(X: np.ndarray, strike_pred: np.ndarray, abs_errors: np.ndarray,
                   rng: np.random.Generator, *, hidden: int = 16, epochs: int = 20, lr: float = 3e-3,
                   dropout: float = 0.2, weight_decay: float = 1e-3) -> AnticipationNet:
    """Train on hits X (N, T, 39) with the prediction (N, 31) and its absolute error (N, 31), m."""
    if not np.isfinite(abs_errors).all() or np.shape(abs_errors) != np.shape(strike_pred):
        raise ValueError(f"fit_error_head: errors {np.shape(abs_errors)} must be finite and shaped like the "
                         f"predictions {np.shape(strike_pred)}")
    target = torch.from_numpy(np.log(np.asarray(abs_errors, np.float32) + ERROR_FLOOR))
    return train_head(X, strike_pred, 1, lambda out, batch: (out[..., 0] - target[batch]).abs().mean(), rng,
                      hidden=hidden, epochs=epochs, lr=lr, dropout=dropout, weight_decay=weight_decay)


@torch.no_grad()
def predict_error(net: AnticipationNet, X: np.ndarray, strike_pred: np.ndarray) -> np.ndarray:
    """(N, 31) predicted absolute error (m, > 0: the floor included) at t = -30 .. 0."""
    return torch.exp(prediction_frames(net(head_inputs(X, strike_pred)))[..., 0]).double().numpy()


def save(net: AnticipationNet, stem, prov: Provenance, schema: Schema = HEAD_SCHEMA) -> None:
    """A head on the anticipation stack (this or another, under its schema): weights + architecture."""
    save_model(net.state_dict(), {"architecture": net.architecture}, stem, schema, prov)


def load(stem, schema: Schema = HEAD_SCHEMA) -> AnticipationNet:
    tensors, hparams = load_model(stem, schema)
    net = AnticipationNet(**hparams["architecture"])
    net.load_state_dict(tensors)
    return net.eval()
