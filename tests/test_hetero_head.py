"""The heteroscedastic head: beta-NLL against the Gaussian NLL and its closed-form minimiser, the beta = 1
mean gradient against the MSE's, and the head learning a toy set's input-dependent noise and bias."""

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from pingpong.common.artifacts import Provenance
from pingpong.learning.models import FRAMES_BEFORE_HIT
from pingpong.uncertainty import hetero_head as head
from pingpong.uncertainty.hetero_head import beta_nll_loss

K = len(FRAMES_BEFORE_HIT)  # the prediction frames t = -30 .. 0


def test_beta_zero_is_torch_gaussian_nll():
    g = torch.Generator().manual_seed(0)
    mean, target = torch.randn(200, generator=g), torch.randn(200, generator=g)
    log_var = 4 * torch.rand(200, generator=g) - 2  # var >= e^-2: above GaussianNLLLoss's 1e-6 clamp
    expected = torch.nn.GaussianNLLLoss(full=False, reduction="mean")(mean, target, torch.exp(log_var))
    assert beta_nll_loss(mean, log_var, target, beta=0.0).item() == pytest.approx(expected.item(), rel=1e-6)


def _constant_fit(y: torch.Tensor, beta: float) -> tuple[float, float]:
    """The constant (mean, log variance) that Adam reaches on the beta-NLL of samples y, from (0, 0)."""
    params = torch.zeros(2, dtype=torch.float64, requires_grad=True)
    optimiser = torch.optim.Adam([params], lr=0.05)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimiser, T_max=1500)
    for _ in range(1500):
        loss = beta_nll_loss(params[0].expand_as(y), params[1].expand_as(y), y, beta)
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        schedule.step()
    return params[0].item(), params[1].item()


@pytest.mark.parametrize("beta", [0.0, 0.5, 1.0])
def test_constant_minimiser_is_sample_mean_and_biased_variance(beta):
    """For constant parameters the weight var ** beta is the same on every term, so the stationary
    point is the Gaussian MLE whatever beta: mean = sample mean, var = sample variance (1/n)."""
    y = torch.from_numpy(np.random.default_rng(1).normal(0.3, 0.2, size=500))  # N(0.3 m, (0.2 m)^2)
    mu, var = y.mean(), y.var(unbiased=False)
    params = torch.tensor([mu.item(), torch.log(var).item()], dtype=torch.float64, requires_grad=True)
    beta_nll_loss(params[0].expand_as(y), params[1].expand_as(y), y, beta).backward()
    assert params.grad.abs().max().item() < 1e-12
    fit_mean, fit_log_var = _constant_fit(y, beta)
    # Adam with a cosine-decayed rate: within 1e-3 sigma of the mean and 1e-3 of the log variance
    assert fit_mean == pytest.approx(mu.item(), abs=1e-3 * 0.2)
    assert fit_log_var == pytest.approx(torch.log(var).item(), abs=1e-3)


values = st.floats(-10, 10, allow_nan=False)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(values, st.floats(-5, 5), values), min_size=1, max_size=20))
def test_beta_one_mean_gradient_is_the_mse_gradient(rows):
    """d/d mean of var * 0.5 (mean - target)^2 / var, averaged: (mean - target) / n, as for 0.5 MSE."""
    mean, log_var, target = torch.tensor(rows, dtype=torch.float64).T
    mean.requires_grad_(True)
    (grad,) = torch.autograd.grad(beta_nll_loss(mean, log_var, target, beta=1.0), mean)
    (mse_grad,) = torch.autograd.grad((0.5 * (mean - target) ** 2).mean(), mean)
    assert torch.allclose(grad, mse_grad, rtol=1e-9, atol=1e-12)
    assert torch.allclose(grad, (mean - target).detach() / len(rows), rtol=1e-9, atol=1e-12)


def _toy_hits(rng: np.random.Generator, n: int, n_frames: int):
    """Hits whose channel 0 reveals if they are hard (shifted +1.5 against -1.5 on every frame);
    residuals: std 0.5 m and bias 0.2 m on hard hits, std 0.05 m and no bias on easy ones."""
    X = rng.normal(size=(n, n_frames, 39)).astype(np.float32)
    hard = rng.uniform(size=n) < 0.5
    X[:, :, 0] += np.where(hard, 1.5, -1.5)[:, None]
    bias_m, std_m = np.where(hard, 0.2, 0.0)[:, None], np.where(hard, 0.5, 0.05)[:, None]
    residuals = bias_m + std_m * rng.normal(size=(n, K))
    return X, rng.normal(0, 0.3, size=(n, K)), residuals, hard


def test_head_learns_heteroscedastic_noise_and_bias():
    """Trained on 150 hits, on 150 unseen ones: the median predicted std of hard hits is > 2.5x the easy
    ones' (true ratio 10; 3.1 .. 6.2 seen over seeds 11 .. 21) and > 1.5x within every prediction frame
    (1.9 .. 2.9 seen); the mean predicted residual is the bias within 0.1 m on hard hits (0.15 .. 0.21
    seen) and 0.05 m on easy ones (|mean| < 0.013 seen). A head that ignored its inputs would give 1x."""
    rng = np.random.default_rng(11)
    X, pred, residuals, hard = _toy_hits(rng, 300, 32)
    net = head.fit_hetero_head(X[:150], pred[:150], residuals[:150], rng, epochs=30)
    mean, std = head.predict_hetero(net, X[150:], pred[150:])
    h = hard[150:]
    assert mean.shape == std.shape == (150, K) and (std > 0).all()
    assert np.median(std[h]) > 2.5 * np.median(std[~h])
    assert (np.median(std[h], axis=0) > 1.5 * np.median(std[~h], axis=0)).all()
    assert abs(mean[h].mean() - 0.2) < 0.1 and abs(mean[~h].mean()) < 0.05


def test_save_load_round_trip_and_input_checks(tmp_path):
    rng = np.random.default_rng(2)
    X, pred, residuals, _ = _toy_hits(rng, 20, 32)
    net = head.fit_hetero_head(X, pred, residuals, rng, epochs=2)
    mean, std = head.predict_hetero(net, X, pred)
    head.save(net, tmp_path / "head", Provenance.of("uncertainty"))
    loaded_mean, loaded_std = head.predict_hetero(head.load(tmp_path / "head"), X, pred)
    assert np.array_equal(loaded_mean, mean) and np.array_equal(loaded_std, std)
    with pytest.raises(ValueError, match="finite"):
        head.fit_hetero_head(X, pred, np.full((20, K), np.nan), rng)
    with pytest.raises(ValueError, match="shaped"):
        head.fit_hetero_head(X, pred, residuals[:19], rng)
    with pytest.raises(ValueError, match="shaped"):
        head.fit_hetero_head(X, pred[:, :-1], residuals, rng)
