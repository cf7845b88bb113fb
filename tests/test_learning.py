"""The learning stage on synthetic tensors: loss, early stopping, training, streaming, saving, grid."""

import json

import numpy as np
import pandas as pd
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from safetensors import safe_open

from pingpong.common.artifacts import Provenance
from pingpong.curation.labels import reflect_frames
from pingpong.frames import N_INPUT, N_PRED_FRAMES
from pingpong.learning.adamw import AdamW
from pingpong.learning.grid import (
    config_id,
    cv_folds,
    expand_grid,
    grid_configurations,
    grid_summary,
    select_best,
)
from pingpong.learning.loss import (
    LATE_FRAMES,
    Y_LOSS,
    Y_POST_BOUNCE,
    Y_PRE_BOUNCE,
    frame_losses,
    late_frame_weights,
    trajectory_loss,
)
from pingpong.learning.models import (
    FRAMES_BEFORE_HIT,
    AnticipationNet,
    load_net,
    prediction_frames,
    prediction_mask,
    save_net,
    with_velocity,
)
from pingpong.learning.streaming import StreamingPredictor
from pingpong.learning.train import (
    EarlyStopping,
    evaluate_loss,
    predict,
    predict_seed_mean,
    strike_points,
    train,
    with_reflections,
)

TINY = dict(rnn_hidden=16, rnn_layers=2, mlp_hidden=16, mlp_layers=1)


@pytest.fixture(autouse=True, scope="module")
def _one_thread():
    """Tiny nets run faster on one thread than on two contended ones (the test machine is shared)."""
    prior = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(prior)


def _labels(rng, n):
    """(a1, a2, b) in the range of real shots: slopes within +-0.3, intercept within +-0.5 m."""
    return np.column_stack([rng.uniform(-0.3, 0.3, n), rng.uniform(-0.3, 0.3, n),
                            rng.uniform(-0.5, 0.5, n)]).astype(np.float32)


def _random_set(rng, n, n_frames=40):
    return rng.normal(size=(n, n_frames, N_INPUT)).astype(np.float32), _labels(rng, n)


# --- optimiser ------------------------------------------------------------------------------------


@pytest.mark.parametrize(("lr", "weight_decay"), [(3e-3, 1e-2), (1e-2, 0.1)])
def test_adamw_is_torchs_bit_for_bit(lr, weight_decay):
    """Our AdamW against torch.optim.AdamW (its CPU path) on a GRU net, 30 steps: the same weights, exactly,
    including a parameter left without a gradient for the first steps (torch counts its steps per
    parameter)."""
    def net():
        torch.manual_seed(0)
        return torch.nn.ModuleDict({"rnn": torch.nn.GRU(5, 8, batch_first=True), "out": torch.nn.Linear(8, 2),
                                    "late": torch.nn.Linear(8, 2)})

    ours, theirs = net(), net()
    opt_ours = AdamW(ours.parameters(), lr=lr, weight_decay=weight_decay)
    opt_theirs = torch.optim.AdamW(theirs.parameters(), lr=lr, weight_decay=weight_decay)
    data = torch.Generator().manual_seed(1)
    for step in range(30):
        x, y = torch.randn(4, 6, 5, generator=data), torch.randn(4, 2, generator=data)
        for model, opt in ((ours, opt_ours), (theirs, opt_theirs)):
            opt.zero_grad()
            h = model["rnn"](x)[0][:, -1]
            loss = ((model["out"](h) - y) ** 2).mean()
            if step >= 5:
                loss = loss + model["late"](h).abs().mean()
            loss.backward()
            opt.step()
    for (name, a), b in zip(ours.named_parameters(), theirs.parameters(), strict=True):
        assert torch.equal(a, b), name
    assert not torch.equal(ours["late"].weight, net()["late"].weight)  # it did train


# --- loss -----------------------------------------------------------------------------------------

def test_loss_positions():
    assert len(Y_PRE_BOUNCE) == 16 and Y_PRE_BOUNCE[0] == 1.40 and Y_PRE_BOUNCE[-1] == -0.10
    assert len(Y_POST_BOUNCE) == 8 and Y_POST_BOUNCE[0] == -0.70 and Y_POST_BOUNCE[-1] == -1.40
    np.testing.assert_allclose(np.diff(Y_LOSS[:16]), -0.1, atol=1e-12)


def test_loss_hand_computed():
    # target (0, 0, 0); prediction (a1, a2, b) = (0.1, 0.2, 0.05):
    #   y = 1.4 .. 0.0 (15 points, a1 line): 0.1 * (sum y = 10.5) + 15 * 0.05 = 1.05 + 0.75 = 1.80
    #   y = -0.1 (a2 line): |0.2 * -0.1 + 0.05| = 0.03
    #   y = -0.7 .. -1.4 (8 points, sum y = -8.4): all negative, |.| sum = 0.2 * 8.4 - 8 * 0.05 = 1.28
    #   frame loss = 3.11 m. A second frame predicts the target exactly (0), a third is masked out
    #   (NaN there must not leak): mean = (3.11 + 0) / 2 = 1.555.
    pred = torch.tensor([[[0.1, 0.2, 0.05], [0.0, 0.0, 0.0], [float("nan")] * 3]])
    mask = torch.tensor([[True, True, False]])
    loss = trajectory_loss(pred, torch.zeros(1, 3), mask)
    assert loss.item() == pytest.approx(1.555, abs=1e-6)


def test_weighted_loss_hand_computed():
    # the hand-computed frames above, weighted 0.2 and 1 (the NaN frame masked out whatever its weight):
    # (0.2 * 3.11 + 1 * 0) / (0.2 + 1) = 0.518333...
    pred = torch.tensor([[[0.1, 0.2, 0.05], [0.0, 0.0, 0.0], [float("nan")] * 3]])
    mask = torch.tensor([[True, True, False]])
    loss = trajectory_loss(pred, torch.zeros(1, 3), mask, torch.tensor([0.2, 1.0, 5.0]))
    assert loss.item() == pytest.approx(0.622 / 1.2, abs=1e-6)


def test_late_frame_weights_mark_the_last_eleven_frames():
    w = late_frame_weights(40, 0.2)
    assert LATE_FRAMES == 11 and w.shape == (40,)
    assert (w[-11:] == 1).all() and torch.allclose(w[:-11], torch.tensor(0.2))


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31 - 1), st.floats(0.01, 1.0), st.floats(0.1, 10.0))
def test_weighted_loss_is_a_weighted_mean(seed, early_weight, scale):
    # equal weights give the paper's loss; any weights give the mean of the per-frame losses weighted
    # by hand, whatever the weights' scale; masked-out frames never count
    g = torch.Generator().manual_seed(seed)
    pred, target = torch.randn(5, 40, 3, generator=g, dtype=torch.float64), torch.randn(5, 3, generator=g)
    mask = torch.rand(5, 40, generator=g) < 0.7
    mask[0, -1] = True
    w = late_frame_weights(40, early_weight).double()
    assert trajectory_loss(pred, target, mask, torch.ones(40)).item() == pytest.approx(
        trajectory_loss(pred, target, mask).item(), rel=1e-12)
    by_hand = (frame_losses(pred, target) * w * mask).sum() / (w * mask).sum()
    assert trajectory_loss(pred, target, mask, scale * w).item() == pytest.approx(by_hand.item(), rel=1e-9)


def _loss_by_loop(p, q):
    """Brute force: x(y) of both paths with the two joined lines, point by point."""
    x = lambda c, y: (c[0] if y >= 0 else c[1]) * y + c[2]  # noqa: E731
    return sum(abs(x(p, y) - x(q, y)) for y in Y_LOSS)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-2, 2), min_size=6, max_size=6))
def test_loss_matches_pointwise_definition(values):
    p, q = np.array(values[:3]), np.array(values[3:])
    loss = trajectory_loss(torch.tensor(p)[None, None], torch.tensor(q)[None], torch.ones(1, 1, dtype=bool))
    assert loss.item() == pytest.approx(_loss_by_loop(p, q), rel=1e-9, abs=1e-9)


def test_strike_point():
    # x(-1.40) = a2 * -1.40 + b = 0.5 * -1.4 + 0.1 = -0.6 m, whatever a1
    assert strike_points(np.array([9.0, 0.5, 0.1])) == pytest.approx(-0.6)


# --- frame indexing -------------------------------------------------------------------------------

def test_prediction_frames_run_from_30_before_the_hit_to_the_hit():
    n_frames = 40
    out = torch.arange(n_frames, dtype=torch.float32)[None, :, None].expand(2, -1, 3)
    cols = prediction_frames(out)[0, :, 0].numpy()
    np.testing.assert_array_equal(cols, n_frames - 1 - FRAMES_BEFORE_HIT)  # indices 9 .. 39; 39 = hit
    assert FRAMES_BEFORE_HIT[0] == 30 and FRAMES_BEFORE_HIT[-1] == 0
    mask = prediction_mask(torch.tensor([40, 5]), n_frames)
    assert mask[0].sum() == N_PRED_FRAMES + 1 and mask[0, -1]
    assert mask[1].nonzero().flatten().tolist() == [35, 36, 37, 38, 39]  # 5 real frames, the hit's included
    short = prediction_frames(torch.zeros(1, 30, 3))  # T = 30: nothing exists 30 frames before the hit
    assert torch.isnan(short[0, 0]).all() and not torch.isnan(short[0, 1:]).any()


def test_a_prediction_sees_its_own_frame_and_none_after():
    rng = np.random.default_rng(1)
    X, _ = _random_set(rng, 3)
    net = AnticipationNet("gru", **TINY)
    before = predict(net, X)
    X[:, -1] += 100.0  # the hit frame: only the last prediction (t = 0) sees it
    after = predict(net, X)
    np.testing.assert_array_equal(after[:, :-1], before[:, :-1])
    assert np.all(np.abs(after[:, -1] - before[:, -1]).max(axis=-1) > 0)


@pytest.mark.parametrize("velocity", [False, True])
def test_padding_is_never_read(velocity):
    rng = np.random.default_rng(2)
    X, _ = _random_set(rng, 1, n_frames=35)
    padded = np.concatenate([np.full((1, 10, N_INPUT), np.nan, np.float32), X], axis=1)
    for cell in ("rnn", "lstm", "gru"):
        net = AnticipationNet(cell, **TINY, velocity=velocity)
        mixed = np.concatenate([padded, rng.normal(size=padded.shape).astype(np.float32)])
        out = net(torch.tensor(mixed), torch.tensor([35, 45])).detach()
        torch.testing.assert_close(out[0, 10:], net(torch.tensor(X))[0].detach(), atol=1e-6, rtol=0)
        assert torch.isnan(out[0, :10]).all()


def test_velocity_is_the_change_per_second_from_each_hits_first_real_frame():
    x = torch.arange(12, dtype=torch.float32).reshape(2, 3, 2) ** 2  # 2 rows, 3 frames, 2 channels
    valid = torch.tensor([[True, True, True], [False, True, True]])  # row 1: one padded frame
    out = with_velocity(x, valid)
    assert out.shape == (2, 3, 4)
    torch.testing.assert_close(out[..., :2], x)
    torch.testing.assert_close(out[0, 1:, 2:], (x[0, 1:] - x[0, :-1]) * 100.0)  # 100 Hz frames
    assert (out[0, 0, 2:] == 0).all() and (out[1, :2, 2:] == 0).all()  # first real frame and padding
    torch.testing.assert_close(out[1, 2, 2:], (x[1, 2] - x[1, 1]) * 100.0)


# --- early stopping -------------------------------------------------------------------------------

def test_early_stopping_scripted():
    # patience 3, min_delta 0.1. Reference: 1.0 (epoch 0); 0.95 is not < 0.9 (wait 1); 0.85 is
    # (reference 0.85, wait 0); 0.80, 0.79, 0.78 are not < 0.75 (wait 1, 2, 3) -> stop at epoch 5.
    # Best weights: the lowest loss seen, 0.78 at epoch 5; the later 0.5 is never reached.
    stopper = EarlyStopping(patience=3, min_delta=0.1)
    losses = [1.0, 0.95, 0.85, 0.80, 0.79, 0.78, 0.5]
    stops = [stopper.step(v) for v in losses[:6]]
    assert stops == [False] * 5 + [True]
    assert (stopper.best_epoch, stopper.best_loss) == (5, 0.78)
    s2 = EarlyStopping(patience=2, min_delta=0.0)
    assert [s2.step(v) for v in [1.0, 1.0, 0.9, 2.0, 0.95]] == [False, False, False, False, True]
    assert s2.best_epoch == 2


def test_training_restores_best_epoch():
    rng = np.random.default_rng(3)
    X, Y = _random_set(rng, 16)
    Xv, Yv = _random_set(rng, 8)  # unrelated validation set: its loss bottoms out early
    net = AnticipationNet("gru", **TINY)
    state, history = train(net, X, Y, Xv, Yv, lr=3e-2, batch_size=8, max_epochs=60, patience=5,
                           min_delta=0.0, seed=0, device="cpu", progress=False)
    val = [h["val_loss"] for h in history]
    best = int(np.argmin(val))
    assert len(history) == best + 6  # stopped exactly 5 epochs after the last improvement
    assert evaluate_loss(net, Xv, Yv) == pytest.approx(val[best], rel=1e-5)
    assert all(torch.equal(state[k], v) for k, v in net.state_dict().items())


# --- training ---------------------------------------------------------------------------------

@pytest.mark.parametrize("cell", ["rnn", "lstm", "gru"])
def test_overfits_a_few_sequences(cell):
    rng = np.random.default_rng(4)
    X, Y = _random_set(rng, 8, n_frames=31)
    net = AnticipationNet(cell, rnn_hidden=32, rnn_layers=1, mlp_hidden=32, mlp_layers=1)
    _, history = train(net, X, Y, X, Y, lr=3e-3, batch_size=8, max_epochs=300, patience=300,
                       min_delta=0.0, seed=0, device="cpu", progress=False)
    # From ~6 m summed over 24 points (25 cm per point) to < 0.125 m (5 mm per point, 2 %): the
    # rest is Adam's step noise on an L1 loss at a fixed learning rate.
    first, best = history[0]["val_loss"], min(h["val_loss"] for h in history)
    assert first > 4.0 and best < 0.125 and best < 0.02 * first


def _trained_weights(seed):
    rng = np.random.default_rng(5)
    X, Y = _random_set(rng, 24)
    net = AnticipationNet("lstm", **{**TINY, "dropout": 0.2}, seed=1)
    lengths = rng.integers(20, 41, 24)
    train(net, X, Y, X[:8], Y[:8], lr=1e-2, batch_size=8, max_epochs=4, patience=10, seed=seed,
          device="cpu", lengths_train=lengths, lengths_val=lengths[:8], progress=False)
    return net.state_dict()


def test_training_is_deterministic_on_cpu():
    a, b, c = _trained_weights(0), _trained_weights(0), _trained_weights(1)
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert not all(torch.equal(a[k], c[k]) for k in a)  # the seed does reach shuffling/dropout


def test_reflection_augment_trains_on_the_hits_and_their_reflections():
    rng = np.random.default_rng(8)
    X, Y = _random_set(rng, 6)
    lengths = np.array([40, 35, 31, 40, 33, 38])
    Xa, Ya, La = with_reflections(X, Y, lengths)
    np.testing.assert_array_equal(Xa[:6], X)
    np.testing.assert_allclose(Xa[6:], reflect_frames(X), rtol=1e-6)
    np.testing.assert_array_equal(Ya[6:], -Y)
    np.testing.assert_array_equal(La, np.tile(lengths, 2))
    net = AnticipationNet("gru", **TINY)
    train(net, X, Y, X, Y, lr=1e-3, max_epochs=1, seed=0, device="cpu", lengths_train=lengths,
          lengths_val=lengths, reflect_augment=True, progress=False)
    real = np.concatenate([Xa[n, 40 - length:] for n, length in enumerate(La)]).astype(np.float64)
    np.testing.assert_allclose(net.normaliser.mean.numpy(), real.mean(0), rtol=1e-5, atol=1e-6)
    assert abs(net.normaliser.mean[36].item()) < 1e-6  # the ball's x: a hit and its reflection cancel


def test_normaliser_uses_training_real_frames_only():
    rng = np.random.default_rng(6)
    X, Y = _random_set(rng, 6)
    X = X * 2.0 + 3.0
    lengths = np.array([40, 35, 31, 40, 33, 38])
    for n, length in enumerate(lengths):
        X[n, : 40 - length] = 1e6  # padding: must not enter the statistics
    Xv = X + 50.0  # validation statistics must not either
    net = AnticipationNet("gru", **TINY)
    train(net, X, Y, Xv, Y, lr=1e-3, max_epochs=1, seed=0, device="cpu", lengths_train=lengths,
          lengths_val=lengths, progress=False)
    real = np.concatenate([X[n, 40 - length:] for n, length in enumerate(lengths)]).astype(np.float64)
    np.testing.assert_allclose(net.normaliser.mean.numpy(), real.mean(0), rtol=1e-6)
    np.testing.assert_allclose(net.normaliser.std.numpy(), real.std(0), rtol=1e-5)


def test_bad_input_is_named():
    rng = np.random.default_rng(7)
    X, Y = _random_set(rng, 4)
    X[2, -3, 5] = np.nan
    with pytest.raises(ValueError, match=r"training part hits \[2\]"):
        train(AnticipationNet("gru", **TINY), X, Y, X, Y, lr=1e-3, device="cpu", progress=False)


def test_learns_more_as_the_hit_approaches():
    # The label is revealed gradually: channels 0-2 carry (a1, a2, b) (scaled to +-1) times an
    # amplitude growing from ~0 to 1 towards the hit, under unit noise; the other channels are
    # constant. Early predictions can only guess the mean (mean |error| ~0.31 m); the strike-point
    # error must fall as the hit approaches.
    rng = np.random.default_rng(8)
    n, n_frames = 400, 40
    Y = _labels(rng, n)
    amplitude = (np.arange(1, n_frames + 1) / n_frames) ** 3
    X = np.zeros((n, n_frames, N_INPUT), np.float32)
    X[:, :, :3] = (rng.normal(size=(n, n_frames, 3))
                   + 4.0 * amplitude[None, :, None] * (Y / np.array([0.3, 0.3, 0.5]))[:, None, :])
    net = AnticipationNet("gru", rnn_hidden=32, rnn_layers=1, mlp_hidden=32, mlp_layers=1)
    train(net, X[:300], Y[:300], X[300:], Y[300:], lr=1e-2, batch_size=50, max_epochs=40, patience=10,
          seed=0, device="cpu", progress=False)
    error = np.abs(strike_points(predict(net, X[300:])) - strike_points(Y[300:, None, :])).mean(0)
    thirds = error[:30].reshape(3, 10).mean(1)  # t = -30..-21, -20..-11, -10..-1 (0 left out)
    assert thirds[0] > thirds[1] > thirds[2]
    assert error[-1] < 0.4 * error[0]


# --- streaming --------------------------------------------------------------------------------

@pytest.mark.parametrize("velocity", [False, True])
@pytest.mark.parametrize("cell", ["rnn", "lstm", "gru"])
def test_streaming_equals_batch(cell, velocity):
    rng = np.random.default_rng(9)
    X, Y = _random_set(rng, 2)
    net = AnticipationNet(cell, **TINY, velocity=velocity)
    net.normaliser.fit(net.features(torch.tensor(X)))
    lengths = torch.tensor([40, 27])  # the second hit starts 13 frames into its (padded) row
    batch = net(torch.tensor(X), lengths).detach().numpy()
    stream = StreamingPredictor(net)
    for n, length in enumerate(lengths.tolist()):
        stream.reset()
        for i in range(40 - length, 40):
            params, strike_x = stream.step(X[n, i])
            np.testing.assert_allclose(params, batch[n, i], atol=1e-5, rtol=0)
            assert strike_x == pytest.approx(float(strike_points(batch[n, i])), abs=1e-5)
    with pytest.raises(ValueError, match="expected 39"):
        stream.step(np.zeros(38))


def test_seed_mean_is_the_mean_path_and_the_mean_strike_point():
    rng = np.random.default_rng(4)
    X, _ = _random_set(rng, 3)
    nets = []
    for seed in (0, 1, 2):
        net = AnticipationNet("gru", **TINY, seed=seed)
        net.normaliser.fit(net.features(torch.tensor(X)))
        nets.append(net)
    each = np.stack([predict(net, X) for net in nets])
    mean = predict_seed_mean(nets, X)
    assert not np.allclose(each[0], each[1])  # the seeds differ, so the mean is not one of them
    np.testing.assert_allclose(mean, each.mean(axis=0), atol=1e-6)
    # the strike point is linear in (a1, a2, b): the mean path strikes at the seeds' mean strike point
    np.testing.assert_allclose(strike_points(mean), strike_points(each).mean(axis=0), atol=1e-6)


# --- saving -----------------------------------------------------------------------------------

def test_save_load_round_trip_without_pickle(tmp_path):
    rng = np.random.default_rng(10)
    X, _ = _random_set(rng, 3)
    net = AnticipationNet("lstm", **TINY, dropout=0.1)
    net.normaliser.fit(X * 3 + 1)
    stem = tmp_path / "model"
    save_net(net, {"lr": 1e-3, "config_id": "abc"}, stem, Provenance.of("learning", {"lr": 1e-3}))
    raw = (tmp_path / "model.safetensors").read_bytes()
    header_len = int.from_bytes(raw[:8], "little")
    assert raw[8:9] == b"{" and json.loads(raw[8 : 8 + header_len])  # safetensors: length + JSON header
    assert not raw.startswith((b"\x80", b"PK"))  # neither a pickle nor torch.save's zip
    with safe_open(str(stem.with_suffix(".safetensors")), "pt") as f:
        assert {"normaliser.mean", "normaliser.std"} <= set(f.keys())
    meta = json.loads(stem.with_suffix(".json").read_text())
    assert meta["hparams"]["architecture"]["cell"] == "lstm" and meta["hparams"]["training"]["lr"] == 1e-3
    loaded = load_net(stem)
    net.eval()
    torch.testing.assert_close(loaded(torch.tensor(X)), net(torch.tensor(X)), atol=0, rtol=0)


# --- grid -------------------------------------------------------------------------------------

def test_expand_grid_ids_are_stable():
    grid = {"cell": ["gru", "lstm"], "rnn_hidden": [8, 16], "lr": [1e-3]}
    configs = expand_grid(grid)
    assert len(configs) == 4 and len({c["config_id"] for c in configs}) == 4
    assert [c["config_id"] for c in configs] == [c["config_id"] for c in expand_grid(dict(grid))]
    reordered = expand_grid({"lr": [1e-3], "rnn_hidden": [16, 8], "cell": ["lstm", "gru"]})
    assert {c["config_id"] for c in reordered} == {c["config_id"] for c in configs}
    with pytest.raises(ValueError, match="'lr' must be a non-empty list"):
        expand_grid({"lr": 1e-3})


def test_cv_folds_partition():
    fold_ids = np.array([0, 1, 2, 0, 1, 2, 2])
    folds = cv_folds(fold_ids)
    assert sorted(folds) == [0, 1, 2]
    for f, (tr, va) in folds.items():
        assert (fold_ids[va] == f).all() and (fold_ids[tr] != f).all()
        np.testing.assert_array_equal(np.sort(np.concatenate([tr, va])), np.arange(7))


def test_select_best_by_mean_over_folds():
    # 'a' (gru) has the single best fold but the worse mean; 'b' (lstm) wins on the mean.
    results = pd.DataFrame({"config_id": ["a"] * 3 + ["b"] * 3, "fold": [0, 1, 2] * 2,
                            "val_loss": [0.1, 0.9, 0.8, 0.4, 0.4, 0.4]})
    assert select_best(results) == "b"
    summary = grid_summary(results)
    assert summary["mean_val_loss"].tolist() == pytest.approx([0.4, 0.6])
    with pytest.raises(ValueError, match="config a lacks folds \\[2\\]"):
        select_best(results.drop(index=2))


GRID_KEYS = {"cell": ["rnn", "lstm", "gru"], "lr": [1e-2, 1e-3, 1e-4], "rnn_hidden": [100, 200, 400]}


@settings(max_examples=30, deadline=None)
@given(sample=st.integers(1, 40), seed=st.integers(0, 2**32 - 1))
def test_grid_sample_is_a_seeded_subset_in_grid_order(sample, seed):
    everything = expand_grid(GRID_KEYS)
    drawn = grid_configurations(GRID_KEYS, sample, {}, np.random.default_rng(seed))
    assert len(drawn) == min(sample, len(everything))
    order = [everything.index(c) for c in drawn]  # a subset of the grid, without repeats, in its order
    assert order == sorted(set(order))
    assert drawn == grid_configurations(GRID_KEYS, sample, {}, np.random.default_rng(seed))


def test_grid_sample_none_is_the_whole_grid_and_extras_join_once():
    inside = {"cell": "rnn", "lr": 1e-3, "rnn_hidden": 100}
    outside = {"cell": "gru", "lr": 3e-3, "rnn_hidden": 64}
    extra = {"inside": inside, "outside": outside, "again": outside}
    configs = grid_configurations(GRID_KEYS, None, extra, np.random.default_rng(0))
    assert len(configs) == 27 + 1  # `inside` is a grid point already; `outside` joins once
    assert configs[-1] == {"config_id": config_id(outside), **outside}
    sliced = grid_configurations(GRID_KEYS, 5, {"outside": outside}, np.random.default_rng(0))
    assert len(sliced) == 6 and sliced[-1]["rnn_hidden"] == 64
    with pytest.raises(ValueError, match="must set exactly the grid's keys"):
        grid_configurations(GRID_KEYS, 5, {"bad": {"cell": "rnn"}}, np.random.default_rng(0))
