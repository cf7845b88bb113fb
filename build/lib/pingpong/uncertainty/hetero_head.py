"""A heteroscedastic head: a small recurrent net that reads a hit's input frames and the final model's
strike-point prediction, and predicts at each of the 31 prediction frames a Gaussian over that
prediction's residual r = y - y_hat: a mean (the point prediction's bias, to correct) and a std (an
aleatoric uncertainty, for normalised conformal, CQR and the aleatoric + epistemic combination).

Like the error head (`error_head`, whose inputs and stack it reuses: AnticipationNet with two outputs,
the residual mean and log variance) it learns from the training hits' out-of-fold residuals, so its
targets are errors on hits the model had not seen. It is trained with beta-NLL (Seitzer et al. 2022):
under the plain Gaussian NLL a badly fitted region can raise its variance instead of moving its mean,
since the mean's gradient is divided by the variance, and the mean stalls there; weighting each term
by the (gradient-free) variance ** beta undoes part of that, and beta = 0.5 is the paper's default.
"""

import math

import numpy as np
import torch

from pingpong.common.artifacts import Provenance, Schema
from pingpong.frames import N_PRED_FRAMES
from pingpong.learning.models import AnticipationNet, prediction_frames
from pingpong.uncertainty import error_head
from pingpong.uncertainty.error_head import head_inputs

# The log variance is softly bounded to std 5 mm .. 3 m. Without a bound a frame whose training
# residuals happen to be tiny drives its variance towards 0 and the 1/var term of the loss explodes on
# the next residual (and a blown-up variance absorbs any residual, so the mean stops learning there).
# A tanh keeps a gradient everywhere, where a hard clamp would leave a frame stuck at the bound.
# Changing the bounds changes what saved outputs mean: bump HEAD_SCHEMA's version.
LOG_VAR_MIN = 2 * math.log(0.005)
LOG_VAR_MAX = 2 * math.log(3.0)
HEAD_SCHEMA = Schema("hetero_head", 1)


def beta_nll_loss(mean: torch.Tensor, log_var: torch.Tensor, target: torch.Tensor,
                  beta: float = 0.5) -> torch.Tensor:
    """beta-NLL (Seitzer et al., "On the Pitfalls of Heteroscedastic Uncertainty Estimation with
    Probabilistic Neural Networks", ICLR 2022), averaged over all elements:

        L = mean( sg[var ** beta] * 0.5 * (log var + (target - mean) ** 2 / var) ),  var = exp(log_var)

    sg: stop-gradient. beta = 0 is the Gaussian NLL without its 0.5 log(2 pi) constant; beta = 1
    gives the mean the gradient of 0.5 * (mean - target) ** 2 (the MSE's)."""
    nll = 0.5 * (log_var + (target - mean) ** 2 * torch.exp(-log_var))
    return (torch.exp(beta * log_var.detach()) * nll).mean()


def _bounded_log_var(raw: torch.Tensor) -> torch.Tensor:
    """The net's raw output -> log variance in (LOG_VAR_MIN, LOG_VAR_MAX), slope 1 at the centre."""
    centre, half = (LOG_VAR_MAX + LOG_VAR_MIN) / 2, (LOG_VAR_MAX - LOG_VAR_MIN) / 2
    return centre + half * torch.tanh(raw / half)


def _mean_log_var(net: AnticipationNet, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(N, 31) residual mean (m) and log variance (m^2) at t = -30 .. 0 for head inputs x (N, T, 40)."""
    out = prediction_frames(net(x))
    return out[..., 0], _bounded_log_var(out[..., 1])


def _check(X: np.ndarray, strike_pred: np.ndarray, residuals: np.ndarray) -> None:
    expected = (len(X), N_PRED_FRAMES + 1)
    for name, values in (("predictions", strike_pred), ("residuals", residuals)):
        if np.shape(values) != expected or not np.isfinite(values).all():
            raise ValueError(f"fit_hetero_head: {name} {np.shape(values)} must be finite and shaped "
                             f"{expected} (hits, prediction frames)")


def fit_hetero_head(X: np.ndarray, strike_pred: np.ndarray, residuals: np.ndarray,
                    rng: np.random.Generator, *, hidden: int = 16, epochs: int = 30, lr: float = 3e-3,
                    dropout: float = 0.2, weight_decay: float = 1e-3, beta: float = 0.5) -> AnticipationNet:
    """Train on hits X (N, T, 39) with the prediction (N, 31) and its out-of-fold residual
    y - y_hat (N, 31), m; outputs per frame: residual mean and raw (unbounded) log variance."""
    _check(X, strike_pred, residuals)
    target = torch.from_numpy(np.asarray(residuals, np.float32))

    def loss_of(out, batch):
        return beta_nll_loss(out[..., 0], _bounded_log_var(out[..., 1]), target[batch], beta)

    return error_head.train_head(X, strike_pred, 2, loss_of, rng, hidden=hidden, epochs=epochs, lr=lr,
                                 dropout=dropout, weight_decay=weight_decay)


@torch.no_grad()
def predict_hetero(net: AnticipationNet, X: np.ndarray,
                   strike_pred: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(mean, std), each (N, 31), m, at t = -30 .. 0: the residual y - y_hat's predicted mean (add it to
    the prediction to correct its bias) and std (5 mm .. 3 m)."""
    net.eval()
    mean, log_var = _mean_log_var(net, head_inputs(X, strike_pred))
    return mean.double().numpy(), torch.exp(0.5 * log_var).double().numpy()


def save(net: AnticipationNet, stem, prov: Provenance) -> None:
    error_head.save(net, stem, prov, HEAD_SCHEMA)


def load(stem) -> AnticipationNet:
    return error_head.load(stem, HEAD_SCHEMA)
