"""The uncertainty verdict: an estimator that knows the errors meets every criterion, noise does not,
and the bootstrap's within-frame Spearman matches scipy's on the unresampled data."""

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
    k = len(FRAMES_BEFORE_HIT)
    n = N_HITS * k
    base = pd.DataFrame({"session": "s00", "rally": np.repeat(np.arange(N_HITS), k), "hit": 0,
                         "split": "test", "frames_before_hit": np.tile(FRAMES_BEFORE_HIT, N_HITS),
                         "strike_x": rng.uniform(-0.7, 0.7, n)})
    err = np.abs(rng.normal(0, 0.1, n)) * rng.lognormal(0, 0.7, N_HITS).repeat(k)
    base["strike_x_pred"] = base["strike_x"] + err * rng.choice([-1, 1], n)
    base["abs_error"] = err

    def table(u, half=None):
        half = np.full(n, np.nan) if half is None else half
        pred = base["strike_x_pred"]
        return base.assign(uncertainty=u, lower=pred - half, upper=pred + half)

    knows = err * np.exp(rng.normal(0.5, 0.4, n))  # covers about 89% of the errors, ranks them well
    wide = np.full(n, np.quantile(err, 0.9))
    return {"ensemble": table(rng.random(n)), "knn": table(rng.random(n)), "conformal": table(wide, wide),
            "knows_the_error": table(knows, knows),
            "noise": table(rng.random(n), wide * rng.uniform(0.5, 1.5, n))}


def test_an_estimator_that_knows_the_errors_meets_every_criterion_and_noise_does_not():
    rng = np.random.default_rng(3)
    tables = _tables(rng)
    verdict = verdict_table(tables, 0.9, rng, n_bootstrap=200).set_index("estimator")
    assert set(verdict.index) == {"knows_the_error", "noise"}
    good, bad = verdict.loc["knows_the_error"], verdict.loc["noise"]
    assert good["meets_all"] and good["spearman_gain"] > 0.4 and good["mean_width_cm"] < 97.5
    assert not bad["clearly_better"] and not bad["meets_all"]
    summary = summary_table({k: tables[k] for k in ("ensemble", "knn", "conformal", "knows_the_error")})
    diagnostics = {"member_error_spearman_within_frame": 0.5,
                   "error_head_training_spearman_within_frame": 0.5}
    summary = pd.concat([summary, summary.iloc[[0]].assign(estimator="error_head")])
    text = verdict_text(verdict.reset_index(), summary, diagnostics, 0.9, tables["ensemble"]["abs_error"])
    assert text.startswith("**Verdict: knows_the_error meet every criterion.**")
    nulls = dict.fromkeys(diagnostics)  # estimators.json writes NaN as null
    assert "errors nan)" in verdict_text(verdict.reset_index(), summary, nulls, 0.9,
                                         tables["ensemble"]["abs_error"])
    where = window_text(by_frame_table(tables))
    assert where.count("knows_the_error") == 2, where
    no_rank = by_frame_table(tables).assign(spearman=np.nan)  # too few test hits to rank within a frame
    assert window_text(no_rank).count("undefined") == 2
    assert "no estimator" in verdict_text(verdict.reset_index().iloc[1:], summary, diagnostics, 0.9,
                                          tables["ensemble"]["abs_error"])


def test_bootstrap_identity_row_is_the_plain_within_frame_spearman():
    rng = np.random.default_rng(4)
    U, E = rng.random((40, 30)), rng.random((40, 30)) + 0.3 * rng.random((40, 1))
    U[:, 0] = 1.0  # a constant frame ranks nothing: counts as 0
    resamples = np.vstack([np.arange(40), rng.integers(0, 40, (5, 40))])
    rho, area = bootstrap_within_frame(U, E, resamples)
    expected = np.mean([0.0] + [stats.spearmanr(U[:, f], E[:, f]).statistic for f in range(1, 30)])
    assert rho.shape == area.shape == (6,) and np.isclose(rho[0], expected) and (area >= 0).all()
