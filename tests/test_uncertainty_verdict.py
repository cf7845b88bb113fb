"""The uncertainty verdict: an estimator that knows the oracle's std meets every bar, noise does not,
without an oracle the verdict ranks by the error, and the bootstrap's within-frame Spearman matches
scipy's on the unresampled data."""

import numpy as np
import pandas as pd
from scipy import stats

from pingpong.learning.models import FRAMES_BEFORE_HIT
from pingpong.reports.uncertainty import by_frame_table, summary_table
from pingpong.reports.uncertainty_verdict import (
    bootstrap_within_frame,
    verdict_table,
    verdict_text,
    window_text,
)

N_HITS = 60


def _tables(rng):
    """Test rows whose errors are Gaussian with a per-(hit, frame) oracle std; estimators that know that
    std, know nothing, or are constant."""
    k = len(FRAMES_BEFORE_HIT)
    n = N_HITS * k
    base = pd.DataFrame({"session": "s00", "rally": np.repeat(np.arange(N_HITS), k), "hit": 0,
                         "split": "test", "frames_before_hit": np.tile(FRAMES_BEFORE_HIT, N_HITS),
                         "strike_x": rng.uniform(-0.7, 0.7, n)})
    # most predictions easy (2 cm), some hard (30 cm); uniform errors, so a central interval of +-0.9 std
    # covers 90 % of each row, and knowing the std halves the width (under Gaussian errors it would save
    # only 10-15 %: the hard rows' exact intervals are wide)
    oracle_std = np.where(rng.random(n) < 0.3, 0.3, 0.02) * rng.lognormal(0, 0.2, n)
    residual = oracle_std * rng.uniform(-1, 1, n)
    base["strike_x_pred"] = base["strike_x"] - residual
    base["abs_error"] = np.abs(residual)
    base["oracle_std"] = oracle_std

    def table(u, half=None):
        half = np.full(n, np.nan) if half is None else half
        pred = base["strike_x_pred"]
        return base.assign(uncertainty=u, lower=pred - half, upper=pred + half, std=u)

    knows = oracle_std * np.exp(rng.normal(0, 0.05, n))  # the oracle's std, nearly exactly
    wide = np.full(n, np.quantile(base["abs_error"], 0.9))
    return {"ensemble": table(rng.random(n)), "knn": table(rng.random(n)), "conformal": table(wide, wide),
            "knows_the_oracle": table(knows, 0.9 * knows),
            "noise": table(rng.random(n), wide * rng.uniform(0.5, 1.5, n))}


def test_an_estimator_that_knows_the_oracle_meets_every_bar_and_noise_does_not():
    rng = np.random.default_rng(3)
    tables = _tables(rng)
    summary = summary_table(tables)
    verdict = verdict_table(tables, summary, 0.9, rng, n_bootstrap=200).set_index("estimator")
    assert list(verdict.index) == list(tables)
    good, bad = verdict.loc["knows_the_oracle"], verdict.loc["noise"]
    assert good["meets_all"] and good["spearman_oracle_1_20"] > 0.9 and good["gain_low95"] > 0.5
    assert good["oracle_low95"] > 0.9 and bad["oracle_high95"] < 0.3
    assert good["spearman_error"] > 0.5 and good["error_low95"] > 0.4  # its std also ranks the errors
    assert not bad["recovers_oracle"] and not bad["meets_all"] and abs(bad["spearman_oracle_1_20"]) < 0.1
    assert verdict.loc["conformal", "width_vs_conformal"] == 1.0 and not verdict.loc["conformal", "narrower"]
    diagnostics = {"member_error_spearman_within_frame": 0.5}
    text = verdict_text(verdict.reset_index(), summary, diagnostics, 0.9)
    assert text.startswith("**Verdict: knows_the_oracle meet every bar.**")
    assert "Most of what could be known: knows_the_oracle" in text
    assert "no estimator" in verdict_text(verdict.reset_index().drop(index=3), summary, {}, 0.9)
    where = window_text(by_frame_table(tables))
    assert where.count("knows_the_oracle") == 2, where  # its std also ranks the Gaussian errors
    no_rank = by_frame_table(tables).assign(spearman=np.nan)  # too few test hits to rank within a frame
    assert window_text(no_rank).count("undefined") == 2


def test_without_an_oracle_the_verdict_ranks_by_the_error():
    rng = np.random.default_rng(8)
    tables = {name: t.assign(oracle_std=np.nan) for name, t in _tables(rng).items()}
    summary = summary_table(tables)
    verdict = verdict_table(tables, summary, 0.9, rng, n_bootstrap=50)
    assert verdict["spearman_oracle_1_20"].isna().all() and not verdict["recovers_oracle"].any()
    text = verdict_text(verdict, summary, {}, 0.9)
    assert "with the absolute error" in text and "knows_the_oracle" in text


def test_bootstrap_identity_row_is_the_plain_within_frame_spearman():
    rng = np.random.default_rng(4)
    U, E = rng.random((40, 30)), rng.random((40, 30)) + 0.3 * rng.random((40, 1))
    U[:, 0] = 1.0  # a constant frame ranks nothing: counts as 0
    resamples = np.vstack([np.arange(40), rng.integers(0, 40, (5, 40))])
    rho = bootstrap_within_frame(U, E, resamples)
    expected = np.mean([0.0] + [stats.spearmanr(U[:, f], E[:, f]).statistic for f in range(1, 30)])
    assert rho.shape == (6,) and np.isclose(rho[0], expected)
