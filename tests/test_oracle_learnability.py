"""The learnability ceiling (pingpong.uncertainty.learnability, rule report_oracle_learnability): a net
trained on the oracle std learns it where the inputs carry it, and the estimators' shares of it."""

import numpy as np
import pandas as pd

from pingpong.frames import N_INPUT
from pingpong.reports.uncertainty_verdict import _row_spearman
from pingpong.stages.report_oracle_learnability import SHARE_BAR, estimator_shares
from pingpong.uncertainty.learnability import error_matrix, fit_on_oracle


def test_a_net_trained_on_the_oracle_learns_a_std_the_inputs_carry():
    """The std of each frame is exp(one input of that frame): the GRU must rank it within a frame far
    better than chance on hits it never saw (the bar 0.7: measured 0.98)."""
    rng = np.random.default_rng(0)
    X = rng.normal(size=(240, 40, N_INPUT)).astype(np.float32)
    std = np.exp(0.5 * X[:, -31:, 5])
    train = np.arange(240) < 160
    u = fit_on_oracle(X, std, train, hidden=16, epochs=12, seed=1)
    rho = _row_spearman(u[~train].T, std[~train].T)  # within each frame, over the held-out hits
    assert np.mean(rho) > 0.7, np.mean(rho)
    noise = fit_on_oracle(X, np.exp(rng.normal(size=std.shape)), train, hidden=16, epochs=12, seed=1)
    assert abs(np.mean(_row_spearman(noise[~train].T, std[~train].T))) < 0.15  # nothing to learn


def test_shares_of_the_ceiling_and_the_bar():
    verdict = pd.DataFrame({"estimator": ["a", "b", "c"], "spearman_oracle_1_20": [0.45, 0.45, 0.2],
                            "oracle_low95": 0.0, "oracle_high95": 1.0, "coverage": [0.91, 0.95, 0.9],
                            "coverage_min_width_tercile": [0.86, 0.9, 0.9]})
    ceiling = pd.Series({"spearman_oracle_1_20": 0.5, "n_hits": 98})
    out = estimator_shares(verdict, ceiling, coverage=0.9).set_index("name")
    assert np.allclose(out["share_of_ceiling"], [0.9, 0.9, 0.4]) and SHARE_BAR == 0.8
    # a: every bar; b: coverage 5 points over nominal; c: a share of 0.4
    assert out["meets_bar"].tolist() == [True, False, False]


def test_error_matrix_places_each_hits_frames_of_the_final_model():
    dataset = pd.DataFrame({"session": ["s00", "s00"], "rally": [1, 2], "hit": [0, 3]})
    predictions = pd.DataFrame({"model": ["final", "final", "ball_only"], "session": "s00",
                                "rally": [2, 1, 1], "hit": [3, 0, 0], "frames_before_hit": [0, 30, 0],
                                "abs_error": [0.2, 0.1, 9.0]})
    errors = error_matrix(dataset, predictions)
    assert errors.shape == (2, 31) and np.isfinite(errors).sum() == 2
    assert errors[0, 0] == 0.1 and errors[1, 30] == 0.2  # t = -30 first; the ball-only model left out
