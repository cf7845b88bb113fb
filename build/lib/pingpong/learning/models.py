"""The anticipation network: a recurrent stack whose every hidden state an MLP maps to (a1, a2, b).

Frame indexing (one convention for training, prediction and streaming):
- An input sequence X (N, T, 39) ends at the hit frame: X[:, T-1] is t = 0 (the hit),
  X[:, T-1-k] is t = -k frames (k * 10 ms before the hit at 100 Hz).
- Output index i of the forward pass is the prediction made with frames up to and including i.
  The model predicts at each frame from 30 before the hit to the hit itself: indices T-31 .. T-1,
  i.e. t = -30 .. 0 (31 predictions; the paper's network outputs 30 x 3 "between 30 frames before
  the hit and 0 frames before", and its robot uses the prediction of t = 0, so the hit frame is kept).
- `prediction_frames(out)` cuts those 31 columns: column k is t = -(30 - k), so column 0 is
  30 frames (0.30 s) before the hit and column 30 is the hit frame (`FRAMES_BEFORE_HIT[k]` frames).
- Velocity inputs (`velocity=True`, beyond the paper): each frame's 39 values are followed by their
  change since the previous frame, per second (0 at a hit's first real frame), so the net sees
  motion without having to learn differencing from a few hundred hits. The streaming step carries
  the previous frame in its state, so batch and stream still agree.
- Variable lengths: padding sits at the front. `lengths` (N,) counts the real frames at the end of
  each sequence; padded frames are never read (their values may be anything, NaN included) and
  the outputs there are NaN. A streaming predictor reset before a hit's first real frame gives
  the same outputs as the batch pass.
"""

import numpy as np
import torch
from torch import nn

from pingpong.common.artifacts import Provenance, Schema, load_model, save_model
from pingpong.frames import FRAME_NS, N_INPUT, N_PRED_FRAMES

FRAMES_BEFORE_HIT = np.arange(N_PRED_FRAMES, -1, -1)  # column k of prediction_frames() -> frames before hit
MODEL_SCHEMA = Schema("anticipation_net", 1)
CELLS = {"rnn": nn.RNN, "lstm": nn.LSTM, "gru": nn.GRU}
_MIN_STD = 1e-6  # a constant input channel is centred but not scaled
FRAME_RATE_HZ = 1e9 / FRAME_NS


def valid_mask(lengths, n_frames: int) -> torch.Tensor:
    """(N, T) bool, True on the real frames: the last `lengths[n]` of each (None: (1, T), all True)."""
    if lengths is None:
        return torch.ones(1, n_frames, dtype=torch.bool)
    lengths = torch.as_tensor(lengths)
    return torch.arange(n_frames, device=lengths.device)[None, :] >= (n_frames - lengths)[:, None]


def prediction_mask(lengths, n_frames: int) -> torch.Tensor:
    """(N, T) bool (None: (1, T)), True at the 31 prediction frames t = -30 .. 0 that hold real input."""
    frames = torch.arange(n_frames)
    in_window = frames >= n_frames - 1 - N_PRED_FRAMES
    lengths = None if lengths is None else torch.as_tensor(lengths).cpu()
    return valid_mask(lengths, n_frames) & in_window[None, :]


def prediction_frames(out: torch.Tensor) -> torch.Tensor:
    """The (N, 31, 3) predictions at t = -30 .. 0 from a forward pass (N, T, 3); NaN before t = -(T-1)."""
    missing = N_PRED_FRAMES + 1 - out.shape[1]
    if missing > 0:
        out = torch.cat([out.new_full((out.shape[0], missing, out.shape[2]), float("nan")), out], dim=1)
    return out[:, -1 - N_PRED_FRAMES:]


def with_velocity(x: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
    """(N, T, C) frames -> (N, T, 2C): each frame, then its change since the previous frame per second;
    0 at each row's first real frame and on padding (valid (N or 1, T): the real frames)."""
    valid = valid.to(x.device).expand(x.shape[0], -1)
    follows = valid & torch.cat([torch.zeros_like(valid[:, :1]), valid[:, :-1]], dim=1)
    prev = torch.cat([x[:, :1], x[:, :-1]], dim=1)
    return torch.cat([x, torch.where(follows[..., None], (x - prev) * FRAME_RATE_HZ, 0.0)], dim=-1)


class Normaliser(nn.Module):
    """Per-channel standardisation; mean and std are buffers so they are saved with the weights."""

    def __init__(self, n_input: int = N_INPUT):
        super().__init__()
        self.register_buffer("mean", torch.zeros(n_input))
        self.register_buffer("std", torch.ones(n_input))

    @torch.no_grad()
    def fit(self, X, lengths=None) -> "Normaliser":
        """Set mean/std from the real frames of X (N, T, C) (the training part only); padding is ignored."""
        X = torch.as_tensor(X)
        frames = X[valid_mask(lengths, X.shape[1]).expand(X.shape[0], -1)].double()
        if len(frames) == 0 or not torch.isfinite(frames).all():
            bad = torch.nonzero(~torch.isfinite(frames).all(-1)).flatten()[:5].tolist()
            raise ValueError(f"Normaliser.fit: need finite real frames; {len(frames)} frames, "
                             f"non-finite at flat frame indices {bad}")
        std = frames.std(0, unbiased=False)
        self.mean.copy_(frames.mean(0))
        self.std.copy_(torch.where(std > _MIN_STD, std, torch.ones_like(std)))
        return self

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return (x - self.mean) / self.std


class AnticipationNet(nn.Module):
    """Recurrent stack (batch_first) + an MLP applied to every hidden state: (N, T, 39) -> (N, T, 3).

    n_output: the MLP's outputs per frame (3: the path parameters; the uncertainty stage's error head
    reuses the stack with one).

    mlp_layers counts the hidden layers of width mlp_hidden (ReLU, dropout) before the linear
    output layer; dropout is also applied between recurrent layers. velocity: append each input's
    change per second (`with_velocity`, see the module docstring). Weights are initialised from
    `seed` without touching torch's global random state.
    """

    def __init__(self, cell: str, *, n_input: int = N_INPUT, rnn_hidden: int, rnn_layers: int,
                 mlp_hidden: int, mlp_layers: int, dropout: float = 0.0, velocity: bool = False,
                 n_output: int = 3, seed: int = 0):
        super().__init__()
        if cell not in CELLS:
            raise ValueError(f"AnticipationNet: cell '{cell}' is not one of {sorted(CELLS)}")
        self.architecture = dict(cell=cell, n_input=n_input, rnn_hidden=rnn_hidden, rnn_layers=rnn_layers,
                                 mlp_hidden=mlp_hidden, mlp_layers=mlp_layers, dropout=dropout,
                                 velocity=bool(velocity), n_output=n_output)
        self.velocity = bool(velocity)
        n_features = 2 * n_input if velocity else n_input
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed)
            self.normaliser = Normaliser(n_features)
            self.rnn = CELLS[cell](n_features, rnn_hidden, rnn_layers, batch_first=True,
                                   dropout=dropout if rnn_layers > 1 else 0.0)
            layers, width = [], rnn_hidden
            for _ in range(mlp_layers):
                layers += [nn.Linear(width, mlp_hidden), nn.ReLU(), nn.Dropout(dropout)]
                width = mlp_hidden
            self.head = nn.Sequential(*layers, nn.Linear(width, n_output))

    def features(self, x: torch.Tensor, lengths=None) -> torch.Tensor:
        """The recurrent stack's input before normalisation: x, with its velocities if the net uses them."""
        return with_velocity(x, valid_mask(lengths, x.shape[1])) if self.velocity else x

    def forward(self, x: torch.Tensor, lengths=None) -> torch.Tensor:
        """(N, T, 3) path parameters after each frame; NaN on padded frames (see module doc)."""
        n_frames = x.shape[1]
        if lengths is None or bool((torch.as_tensor(lengths) == n_frames).all()):
            return self.head(self.rnn(self.normaliser(self.features(x)))[0])
        lengths = torch.as_tensor(lengths, device=x.device)
        valid = valid_mask(lengths, n_frames)
        z = self.normaliser(self.features(torch.where(valid[..., None], x, 0.0), lengths))
        # Rotate each row's real frames to the front, run the plain (fused) RNN, rotate back. The
        # recurrence is causal, so the padding now trailing each row never reaches the real frames'
        # outputs, and every row starts from the zero state at its first real frame. (Packed
        # sequences do the same but their CPU backward is ~4x slower.)
        shift = (n_frames - lengths)[:, None]
        steps = torch.arange(n_frames, device=x.device)[None, :]
        to_front = ((steps + shift) % n_frames)[..., None].expand_as(z)
        h_front = self.rnn(z.gather(1, to_front))[0]
        to_back = ((steps - shift) % n_frames)[..., None].expand(-1, -1, h_front.shape[-1])
        out = self.head(h_front.gather(1, to_back))
        return torch.where(valid[..., None], out, float("nan"))

    def step(self, frame: torch.Tensor, state=None):
        """One frame (N, 39) -> ((N, 3) path parameters, new state); state=None starts a hit.

        The state is the recurrent state and the frame itself (for the next frame's velocity)."""
        hidden, prev = (None, None) if state is None else state
        z = frame
        if self.velocity:
            change = torch.zeros_like(frame) if prev is None else (frame - prev) * FRAME_RATE_HZ
            z = torch.cat([frame, change], dim=-1)
        h, hidden = self.rnn(self.normaliser(z)[:, None, :], hidden)
        return self.head(h[:, 0]), (hidden, frame)


def save_net(net: AnticipationNet, hparams: dict, stem, prov: Provenance) -> None:
    """Weights (normaliser included) to {stem}.safetensors; architecture + `hparams` (training
    settings, config id, ...) + provenance to {stem}.json."""
    save_model(net.state_dict(), {"architecture": net.architecture, "training": hparams}, stem,
               MODEL_SCHEMA, prov)


def load_net(stem) -> AnticipationNet:
    """The network saved by `save_net`, in eval mode on the CPU (no pickle involved)."""
    tensors, meta = load_model(stem, MODEL_SCHEMA)
    net = AnticipationNet(**meta["architecture"])
    net.load_state_dict(tensors)
    return net.eval()
