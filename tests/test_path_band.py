"""Whole-path conformal bands: the simultaneous band covers the whole path per frame within the finite-sample
bound where the pointwise band does not, path_x and the table against hand-computed cases, nesting in alpha,
the state round trip and clear failures."""

import json

import numpy as np
import pytest
from conftest import coverage_bounds
from hypothesis import given, settings
from hypothesis import strategies as st

from pingpong.frames import STRIKE_Y
from pingpong.uncertainty.path_band import (
    POINTWISE,
    SIMULTANEOUS,
    Y_BAND,
    PathBand,
    apply_band,
    fit_path_band,
    fit_pointwise_band,
    path_band_table,
    path_x,
    whole_path_covered,
)

ALPHA = 0.1
TRIALS = 200  # calibration draws; each trial's coverage is measured on its own test hits
FRAMES = np.array([0, 30])  # frames before the hit
NOISE_M = np.array([0.02, 0.10])  # residual scale per frame: the error grows with the time before the hit


def _hits(rng, n_hits: int) -> tuple:
    """(pred, true, frames, groups): one row per hit and frame; a hit's true path is shared by its frames, and
    each row's error is a random slope on each line and a random offset, so it is correlated along y."""
    k = len(FRAMES)
    true = np.repeat(rng.normal(0, [0.3, 0.3, 0.2], size=(n_hits, 3)), k, axis=0)
    sd = np.tile(NOISE_M, n_hits) * np.repeat(rng.lognormal(0, 0.3, n_hits), k)  # hits differ in difficulty
    error = rng.normal(size=(n_hits * k, 3)) * np.array([0.5, 0.5, 1.0]) * sd[:, None]
    return true + error, true, np.tile(FRAMES, n_hits), np.repeat(np.arange(n_hits), k)


def _inside(band, test) -> np.ndarray:
    pred, true, frames, _ = test
    lower, upper = apply_band(band, pred, frames)
    x = path_x(true, band.y)
    return (lower <= x) & (x <= upper)


def test_simultaneous_band_covers_the_whole_path_where_the_pointwise_band_does_not():
    rng = np.random.default_rng(0)
    n_train, n_cal, n_test = 200, 40, 100
    whole, pointwise_whole, pointwise_at_y = [], [], []
    for _ in range(TRIALS):
        train, cal, test = _hits(rng, n_train), _hits(rng, n_cal), _hits(rng, n_test)
        simultaneous = fit_path_band(*train[:3], *cal, ALPHA)
        pointwise = fit_pointwise_band(*cal, ALPHA)
        covered = whole_path_covered(*apply_band(simultaneous, test[0], test[2]), test[1])
        whole.append([covered[test[2] == f].mean() for f in FRAMES])
        inside = _inside(pointwise, test)
        pointwise_whole.append([inside[test[2] == f].all(axis=1).mean() for f in FRAMES])
        pointwise_at_y.append([inside[test[2] == f].mean(axis=0) for f in FRAMES])
    whole, pointwise_whole, pointwise_at_y = map(np.array, (whole, pointwise_whole, pointwise_at_y))
    for i in range(len(FRAMES)):
        low, high = coverage_bounds(n_cal, whole[:, i], ALPHA)
        assert low <= whole[:, i].mean() <= high
        assert pointwise_whole[:, i].mean() < 1 - ALPHA - 0.05  # each y at 1 - alpha, all at once less often
        for j in range(len(Y_BAND)):
            low, high = coverage_bounds(n_cal, pointwise_at_y[:, i, j], ALPHA)
            assert low <= pointwise_at_y[:, i, j].mean() <= high


def test_path_x_hand_computed_on_both_lines_and_the_join():
    params = np.array([0.5, -0.2, 0.1])  # (a1, a2, b)
    y = np.array([1.0, 1e-9, 0.0, -1e-9, STRIKE_Y])
    assert np.allclose(path_x(params, y), [0.6, 0.1, 0.1, 0.1, 0.1 + 0.28])  # continuous at the join, y = 0
    batch = np.stack([params, [0.0, 1.0, -0.5]])[:, None, :].repeat(4, axis=1)  # (2, 4, 3)
    x = path_x(batch)
    assert x.shape == (2, 4, len(Y_BAND))
    assert np.allclose(x[1, 3], np.where(Y_BAND < 0, Y_BAND, 0.0) - 0.5)
    assert len(Y_BAND) == 57 and Y_BAND[0] == 1.40 and Y_BAND[-1] == -1.40 and 0.0 in Y_BAND


def test_path_band_table_hand_computed():
    # frame 0: half-width 0.10 m, frame 5: 0.20 m at every y; every prediction the path x = 0
    band = PathBand(SIMULTANEOUS, ALPHA, Y_BAND, (0, 5), np.ones((2, len(Y_BAND))), np.array([[0.1], [0.2]]))
    frames = np.array([0, 0, 5, 5, 5])
    true = np.array([
        [0.0, 0.0, 0.05],  # inside everywhere
        [0.0, 0.0, 0.15],  # outside everywhere
        [0.0, 0.1, 0.0],  # x(-1.40) = -0.14: inside the 0.20 m of frame 5
        [0.2, 0.0, 0.0],  # x(1.40) = 0.28: outside before the bounce, inside at the strike line (x = 0)
        [0.0, 0.2, 0.0],  # x(-1.40) = -0.28: outside at the strike line
    ])
    table = path_band_table([band], np.zeros((5, 3)), true, frames)
    row = table.loc[SIMULTANEOUS]
    assert row["whole_path_coverage"] == pytest.approx(2 / 5)
    assert row["whole_path_coverage_min_frame"] == pytest.approx(1 / 3) and row["worst_frame"] == 5
    assert row["strike_point_coverage"] == pytest.approx(3 / 5)
    assert row["mean_half_width_cm"] == pytest.approx(16.0)  # (2 * 10 + 3 * 20) / 5 cm
    assert row["strike_half_width_cm"] == pytest.approx(16.0)
    with pytest.raises(ValueError, match="one band per kind"):
        path_band_table([band, band], np.zeros((5, 3)), true, frames)


@settings(max_examples=10)
@given(st.integers(0, 2**16), st.floats(0.05, 0.6), st.floats(0.05, 0.6))
def test_band_contains_the_prediction_and_widens_as_alpha_falls(seed, a, b):
    rng = np.random.default_rng(seed)
    train, cal, test = _hits(rng, 30), _hits(rng, 30), _hits(rng, 10)
    low_alpha, high_alpha = sorted((a, b))
    x = path_x(test[0])
    for fit in (lambda alpha: fit_path_band(*train[:3], *cal, alpha),
                lambda alpha: fit_pointwise_band(*cal, alpha)):
        wide, narrow = (apply_band(fit(alpha), test[0], test[2]) for alpha in (low_alpha, high_alpha))
        assert (wide[0] <= narrow[0]).all() and (narrow[0] <= x).all()
        assert (x <= narrow[1]).all() and (narrow[1] <= wide[1]).all()


def test_state_round_trip_gives_the_same_band():
    rng = np.random.default_rng(1)
    train, cal, test = _hits(rng, 50), _hits(rng, 30), _hits(rng, 20)
    few = fit_pointwise_band(*(v[:10] for v in cal), ALPHA)  # 5 hits: too few for 1 - alpha
    assert few.kind == POINTWISE and np.isinf(few.quantile).all()  # json writes Infinity and reads it back
    for band in (fit_path_band(*train[:3], *cal, ALPHA), fit_pointwise_band(*cal, ALPHA), few):
        again = PathBand.from_state(json.loads(json.dumps(band.state())))
        assert (again.kind, again.alpha, again.frames) == (band.kind, band.alpha, band.frames)
        assert np.array_equal(again.y, band.y) and np.array_equal(again.scale, band.scale)
        assert np.array_equal(again.quantile, band.quantile)
        for mine, theirs in zip(apply_band(band, test[0], test[2]), apply_band(again, test[0], test[2]),
                                strict=True):
            assert np.array_equal(mine, theirs)


def test_fails_clearly_on_bad_inputs():
    rng = np.random.default_rng(2)
    train, cal = _hits(rng, 20), _hits(rng, 20)
    pred, true, frames, groups = cal
    with pytest.raises(ValueError, match=r"expected \(rows, 3\)"):
        fit_pointwise_band(pred[:, :2], true, frames, groups, ALPHA)
    with pytest.raises(ValueError, match=r"expected \(40, 3\)"):
        fit_pointwise_band(pred, true[:-1], frames, groups, ALPHA)
    with pytest.raises(ValueError, match=r"frames: expected \(40,\)"):
        fit_pointwise_band(pred, true, frames[:-1], groups, ALPHA)
    with pytest.raises(ValueError, match=r"groups: expected \(40,\)"):
        fit_pointwise_band(pred, true, frames, groups[:-1], ALPHA)
    with pytest.raises(ValueError, match="finite"):
        fit_pointwise_band(np.where(np.arange(40)[:, None] == 3, np.nan, pred), true, frames, groups, ALPHA)
    only_0 = frames == 0
    with pytest.raises(ValueError, match=r"calibration rows for every training frame; frames \[30\]"):
        fit_path_band(*train[:3], pred[only_0], true[only_0], frames[only_0], groups[only_0], ALPHA)
    with pytest.raises(ValueError, match=r"training rows for every calibration frame; frames \[30\]"):
        fit_path_band(train[0][::2], train[1][::2], train[2][::2], *cal, ALPHA)
    band = fit_pointwise_band(*cal, ALPHA)
    with pytest.raises(ValueError, match=r"frames with calibration rows \[0, 30\]; frames \[7\]"):
        apply_band(band, pred[:2], [0, 7])
    with pytest.raises(ValueError, match="lower and upper"):
        whole_path_covered(np.zeros((2, 3)), np.zeros((2, 3)), true[:2])
