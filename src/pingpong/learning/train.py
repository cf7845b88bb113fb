"""Training with AdamW and early stopping, batch prediction, strike points.

Determinism: weights are initialised from the net's own seed (models.AnticipationNet); here the
shuffling uses a torch.Generator seeded with `seed` and dropout draws from torch's global stream,
re-seeded with `seed` inside a forked random state (the caller's stream is left as it was). Two runs
with the same seed on the CPU give identical weights (the CPU kernels these nets use are deterministic);
on CUDA, torch.use_deterministic_algorithms is on (warn only) for the run, and cuDNN's RNN kernels may
still differ in the last bits. Not on the CPU: the switch imports torch's compiler stack, as
torch.optim does (`adamw`), 1.5-2.3 s a process.
"""

import logging
import math
import time
from contextlib import contextmanager

import numpy as np
import torch
from tqdm.auto import tqdm

from pingpong.curation.labels import reflect_frames, reflect_labels
from pingpong.frames import STRIKE_Y
from pingpong.learning.adamw import AdamW
from pingpong.learning.loss import frame_losses, late_frame_weights, trajectory_loss
from pingpong.learning.models import AnticipationNet, prediction_frames, prediction_mask, valid_mask

log = logging.getLogger(__name__)


class EarlyStopping:
    """Stop once the validation loss has not beaten the reference by more than `min_delta` for
    `patience` epochs in a row (the reference is the last loss that did, as in Keras/Lightning).
    Separately tracks the lowest loss seen (`best_loss`, `best_epoch`): the weights to restore.
    """

    def __init__(self, patience: int, min_delta: float):
        self.patience, self.min_delta = patience, min_delta
        self.reference = self.best_loss = math.inf
        self.best_epoch = self.epoch = -1
        self.wait = 0

    def step(self, loss: float) -> bool:
        """Record one epoch's validation loss; True when training should stop after this epoch."""
        self.epoch += 1
        if loss < self.best_loss:
            self.best_loss, self.best_epoch = loss, self.epoch
        if loss < self.reference - self.min_delta:
            self.reference, self.wait = loss, 0
        else:
            self.wait += 1
        return self.wait >= self.patience


@contextmanager
def _deterministic_on_cuda(dev: torch.device):
    """torch.use_deterministic_algorithms on (warn only) while in the block on CUDA, then as it was; nothing
    on the CPU (module docstring)."""
    if dev.type != "cuda":
        yield
        return
    prior = (torch.are_deterministic_algorithms_enabled(),
             torch.is_deterministic_algorithms_warn_only_enabled())
    torch.use_deterministic_algorithms(True, warn_only=True)
    try:
        yield
    finally:
        torch.use_deterministic_algorithms(prior[0], warn_only=prior[1])


def resolve_device(device: str) -> torch.device:
    """'auto' -> CUDA when present, else CPU; 'cpu'/'cuda' as given."""
    if device == "auto":
        device = "cuda" if torch.cuda.is_available() else "cpu"
    return torch.device(device)


def _check_inputs(X: torch.Tensor, Y: torch.Tensor, lengths, name: str, n_input: int) -> None:
    """Fail clearly on wrong shapes or non-finite real frames/labels (padding may hold anything)."""
    if X.ndim != 3 or X.shape[2] != n_input or Y.shape != (X.shape[0], 3):
        raise ValueError(f"train: {name} has X {tuple(X.shape)}, Y {tuple(Y.shape)}; expected X (N, T, "
                         f"{n_input}) and Y (N, 3) = (a1, a2, b)")
    real = valid_mask(lengths, X.shape[1]).expand(X.shape[0], -1)
    bad = ~(torch.isfinite(X).all(-1) | ~real).all(-1) | ~torch.isfinite(Y).all(-1)
    if bad.any():
        raise ValueError(f"train: {name} hits {torch.nonzero(bad).flatten()[:10].tolist()} hold "
                         "non-finite input frames or labels")


@torch.no_grad()
def evaluate_loss(net: AnticipationNet, X, Y, lengths=None, batch_size: int = 500) -> float:
    """`trajectory_loss` over the whole set (exact mean over all prediction frames), in eval mode."""
    net.eval()
    device = next(net.parameters()).device
    X, Y = torch.as_tensor(X, dtype=torch.float32), torch.as_tensor(Y, dtype=torch.float32)
    mask = prediction_mask(lengths, X.shape[1]).expand(X.shape[0], -1)
    total, count = 0.0, 0
    for idx in torch.arange(len(X)).split(batch_size):
        lengths_b = None if lengths is None else torch.as_tensor(lengths)[idx]
        losses = frame_losses(net(X[idx].to(device), lengths_b), Y[idx].to(device))
        m = mask[idx].to(device)
        total += losses[m].sum().item()
        count += int(m.sum())
    return total / count


def with_reflections(X, Y, lengths=None):
    """The hits (X (N, T, C), Y (N, 3), lengths (N,) or None) followed by their left-right reflections
    (pingpong.curation.labels.reflect_frames, reflect_labels): twice the hits, a player of each hand.

    Beyond the paper. On the 434 training hits of the default run of de4fc9f (GRU 1 x 64, early frames
    weighted 0.2, out of fold, the mean of 3 seeds) the median strike error 10 / 5 / 1 frame(s) before the
    hit fell from 23.1 / 20.0 / 17.4 cm to 21.4 / 16.7 / 15.2 cm; 30 frames before it rose from 30.4 to
    33.1 cm, where the body's handedness is most of what the inputs show.
    """
    X, Y = np.asarray(X, np.float32), np.asarray(Y, np.float32)
    X = np.concatenate([X, reflect_frames(X).astype(np.float32)])
    Y = np.concatenate([Y, reflect_labels(Y).astype(np.float32)])
    return X, Y, None if lengths is None else np.concatenate([np.asarray(lengths)] * 2)


def train(net: AnticipationNet, X_train, Y_train, X_val, Y_val, lr: float, *, batch_size: int = 500,
          max_epochs: int = 200, patience: int = 30, min_delta: float = 0.01, early_frame_weight: float = 1.0,
          reflect_augment: bool = False, seed: int = 0, device: str = "auto", lengths_train=None,
          lengths_val=None, progress: bool = True):
    """Fit `net` in place; returns (best_state, history).

    X (N, T, 39) float32, Y (N, 3); lengths (N,) real frames per sequence (None: no padding). The
    net's normaliser is fitted here on the training part (real frames only). AdamW with PyTorch's
    defaults except lr; the loss is `trajectory_loss` over the 31 prediction frames, those before
    t = -10 weighted by early_frame_weight (1: the paper's loss; `loss.late_frame_weights`).
    reflect_augment: train on the training hits and their left-right reflections (`with_reflections`). Early
    stopping as `EarlyStopping` on the unweighted validation loss; at the end the weights of the lowest
    validation loss are loaded, and the net is left on the CPU in eval mode. best_state: those weights
    (CPU tensors). history: one dict per epoch: epoch, train_loss (mean over the epoch's batches, weighted),
    val_loss, seconds.
    """
    if reflect_augment:
        X_train, Y_train, lengths_train = with_reflections(X_train, Y_train, lengths_train)
    X_train, Y_train, X_val, Y_val = (torch.as_tensor(a, dtype=torch.float32)
                                      for a in (X_train, Y_train, X_val, Y_val))
    n_input = net.architecture["n_input"]
    _check_inputs(X_train, Y_train, lengths_train, "training part", n_input)
    _check_inputs(X_val, Y_val, lengths_val, "validation part", n_input)
    dev = resolve_device(device)
    net.normaliser.fit(net.features(X_train, lengths_train), lengths_train)
    net.to(dev)
    X_dev, Y_dev = X_train.to(dev), Y_train.to(dev)
    L_dev = None if lengths_train is None else torch.as_tensor(lengths_train).to(dev)
    mask_dev = prediction_mask(lengths_train, X_train.shape[1]).expand(len(X_train), -1).to(dev)
    weights_dev = late_frame_weights(X_train.shape[1], early_frame_weight).to(dev)
    optimiser = AdamW(net.parameters(), lr=lr)
    shuffle = torch.Generator().manual_seed(seed)
    stopper = EarlyStopping(patience, min_delta)
    history, best_state = [], None
    cuda_devices = [dev.index or 0] if dev.type == "cuda" else []
    with _deterministic_on_cuda(dev), torch.random.fork_rng(devices=cuda_devices):
        torch.manual_seed(seed)
        bar = tqdm(range(max_epochs), desc="train", unit="epoch", disable=not progress)
        for epoch in bar:
            start = time.perf_counter()
            net.train()
            total = torch.zeros((), device=dev)
            batches = torch.randperm(len(X_dev), generator=shuffle).split(batch_size)
            for idx in batches:
                idx = idx.to(dev)
                out = net(X_dev[idx], None if L_dev is None else L_dev[idx])
                loss = trajectory_loss(out, Y_dev[idx], mask_dev[idx], weights_dev)
                optimiser.zero_grad()
                loss.backward()
                optimiser.step()
                total += loss.detach()
            train_loss = total.item() / len(batches)
            val_loss = evaluate_loss(net, X_val, Y_val, lengths_val, batch_size)
            if not (math.isfinite(train_loss) and math.isfinite(val_loss)):
                raise FloatingPointError(f"train: loss became train={train_loss}, val={val_loss} at "
                                         f"epoch {epoch} (lr={lr}); try a lower learning rate")
            stop = stopper.step(val_loss)
            if stopper.best_epoch == epoch:
                best_state = {k: v.detach().cpu().clone() for k, v in net.state_dict().items()}
            history.append(dict(epoch=epoch, train_loss=train_loss, val_loss=val_loss,
                                seconds=time.perf_counter() - start))
            bar.set_postfix(train=f"{train_loss:.4f}", val=f"{val_loss:.4f}", best=stopper.best_epoch)
            if stop:
                break
    log.info("trained %d epochs; best val loss %.4f at epoch %d", len(history), stopper.best_loss,
             stopper.best_epoch)
    net.cpu().load_state_dict(best_state)
    net.eval()
    return best_state, history


@torch.no_grad()
def predict(net: AnticipationNet, X, lengths=None, batch_size: int = 500) -> np.ndarray:
    """(N, 31, 3) float32 (a1, a2, b) at t = -30 .. 0 (column k is 30 - k frames before the hit);
    NaN where that frame is padding. Runs on the net's device, in eval mode."""
    net.eval()
    device = next(net.parameters()).device
    X = torch.as_tensor(X, dtype=torch.float32)
    chunks = []
    for idx in torch.arange(len(X)).split(batch_size):
        lengths_b = None if lengths is None else torch.as_tensor(lengths)[idx]
        chunks.append(prediction_frames(net(X[idx].to(device), lengths_b)).cpu())
    return torch.cat(chunks).numpy()


def predict_seed_mean(nets, X, lengths=None) -> np.ndarray:
    """`predict` averaged over nets (the seeds of one configuration): a deep ensemble's point prediction
    (Lakshminarayanan et al. 2017). The strike point is linear in (a1, a2, b), so it is the seeds'
    mean strike point too. On the default run of 2026-12-02 (16 rallies a session, 121 test hits) five
    seeds' mean had a median strike error of 26.6 / 23.2 cm 10 / 1 frames before the hit, the seeds alone
    27.2-29.9 / 22.0-28.8 cm (analysis/seed_average.py)."""
    return np.mean([predict(net, X, lengths) for net in nets], axis=0)


def strike_points(pred):
    """Strike-point x (m) of paths (..., 3) at the strike line y = STRIKE_Y (< 0: the a2 line).

    `predict`'s (N, 31, 3) gives (N, 31); works on numpy arrays and torch tensors alike.
    """
    return pred[..., 1] * STRIKE_Y + pred[..., 2]
