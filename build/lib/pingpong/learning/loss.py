"""The paper's trajectory loss: summed |x(y) - x^(y)| over fixed y positions along the table.

A hit's post-hit path is two joined lines in the mirrored table frame, parameterised by
(a1, a2, b): x(y) = a1*y + b for y >= 0 (the hitter's half, before the bounce) and a2*y + b for
y < 0 (after it). The loss compares predicted and true x at
  pre-bounce y in {1.40, 1.30, ..., 0.00, -0.10} m  (16 points; -0.10 falls on the a2 line) and
  post-bounce y in {-0.70, -0.80, ..., -1.40} m      (8 points),
24 points in all, so one frame's loss is in metres summed over 24 points (a loss of 0.24 is a
mean error of 1 cm per point). The batch loss is the mean over every (hit, frame) pair that the
frame mask selects, so each counted prediction weighs the same whatever its hit's length.

Beyond the paper, training may weigh the frames before t = -10 less (`late_frame_weights`): the robot acts
on the predictions of t = -10 .. 0, and the earlier frames, whose inputs carry little of the strike point,
otherwise fill the shared weights with their noise (measured in config/config.yaml).
"""

import numpy as np
import torch

Y_PRE_BOUNCE = np.round(np.arange(1.40, -0.10 - 1e-9, -0.10), 2)  # 16 values, m
Y_POST_BOUNCE = np.round(np.arange(-0.70, -1.40 - 1e-9, -0.10), 2)  # 8 values, m
Y_LOSS = np.concatenate([Y_PRE_BOUNCE, Y_POST_BOUNCE])


def path_design(y: np.ndarray) -> np.ndarray:
    """(3, len(y)) matrix D with x(y) = (a1, a2, b) @ D: x is linear in the labels at fixed y."""
    y = np.asarray(y, dtype=np.float64)
    return np.stack([np.where(y >= 0, y, 0.0), np.where(y < 0, y, 0.0), np.ones_like(y)])


LATE_FRAMES = 11  # t = -10 .. 0: the frames the paper's robot acts on (alpha1 at t = -10, alpha2 at 0)
_LOSS_DESIGN = torch.from_numpy(path_design(Y_LOSS))  # float64; cast to the prediction dtype on use


def frame_losses(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Per-frame loss (N, T): sum over the 24 y positions of |x_pred(y) - x_true(y)| (m).

    pred (N, T, 3), target (N, 3). The difference of x is the path of the label difference
    because x is linear in (a1, a2, b).
    """
    design = _LOSS_DESIGN.to(device=pred.device, dtype=pred.dtype)
    return ((pred - target[:, None, :]) @ design).abs().sum(-1)


def late_frame_weights(n_frames: int, early_weight: float) -> torch.Tensor:
    """(n_frames,) loss weights: 1 on the last LATE_FRAMES frames (t = -10 .. 0), early_weight before."""
    weights = torch.full((n_frames,), float(early_weight))
    weights[-LATE_FRAMES:] = 1.0
    return weights


def trajectory_loss(pred: torch.Tensor, target: torch.Tensor, frame_mask: torch.Tensor,
                    frame_weights: torch.Tensor | None = None) -> torch.Tensor:
    """Mean of `frame_losses` over the (hit, frame) pairs where frame_mask (N, T) is True, weighted by
    frame_weights (T,) when given (a weighted mean: the weights' scale does not matter).

    Masked-out frames are dropped, not multiplied by zero, so NaN predictions there (padding)
    cannot leak into the loss.
    """
    losses = frame_losses(pred, target)[frame_mask]
    if frame_weights is None:
        return losses.mean()
    weights = frame_weights.to(losses)[None, :].expand_as(frame_mask)[frame_mask]
    return (losses * weights).sum() / weights.sum()

