"""The project's split conformal quantiles against a maintained library (crepes' ConformalRegressor) on the
same scores and calibration split: plain, normalised (sigmas) and Mondrian (bins).

With one score per hit, `conformal_quantile` is the ceil((1 - alpha)(n + 1))-th smallest score. crepes
computes that rank as int(alpha (n + 1)) from the top in floating point: where (1 - alpha)(n + 1) is a whole
number, alpha (n + 1) can round just below it (0.2 * 25 = 4.999...) and crepes then takes the next larger
score. So the two agree exactly, except at those whole ranks, where crepes' is the next order statistic.
"""

import warnings

import crepes
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from pingpong.uncertainty.conformal import conformal_quantile, mondrian_quantiles, normalised_scores

ALPHAS = st.sampled_from([0.05, 0.1, 0.2, 0.25, 0.5])
SCORES = arrays(np.float64, st.integers(5, 300), elements=st.floats(0.0, 10.0, allow_subnormal=False))


def crepes_half_width(scores, alpha: float, sigmas=None, bins=None, at_bin=None) -> float:
    """crepes' interval half-width for y_hat = 0 (and sigma 1 / the given bin) at confidence 1 - alpha."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # too few calibration scores: infinite intervals
        regressor = crepes.ConformalRegressor().fit(residuals=scores, sigmas=sigmas, bins=bins)
        interval = regressor.predict_int(np.zeros(1), sigmas=None if sigmas is None else np.ones(1),
                                         bins=None if bins is None else np.array([at_bin]),
                                         confidence=1 - alpha)
    return float(interval[0, 1])


def assert_same_quantile(ours: float, theirs: float, scores, alpha: float):
    s = np.sort(scores)
    rank = (1 - alpha) * (len(s) + 1)
    if np.isinf(ours):
        assert np.isinf(theirs)
    elif abs(rank - round(rank)) < 1e-9:  # a whole rank: crepes may take the next order statistic
        k = int(round(rank)) - 1
        assert theirs in (ours, s[min(k + 1, len(s) - 1)], np.inf)
    else:
        assert ours == theirs


@settings(max_examples=300)
@given(SCORES, ALPHAS)
def test_plain_split_conformal_matches_crepes(scores, alpha):
    assert_same_quantile(conformal_quantile(scores, alpha), crepes_half_width(scores, alpha), scores, alpha)


@settings(max_examples=200)
@given(SCORES, ALPHAS, st.integers(0, 2**32 - 1))
def test_normalised_conformal_matches_crepes(abs_errors, alpha, seed):
    sigmas = np.random.default_rng(seed).uniform(0.1, 2.0, len(abs_errors))
    scores = normalised_scores(abs_errors, sigmas)
    theirs = crepes_half_width(abs_errors, alpha, sigmas=sigmas)
    assert_same_quantile(conformal_quantile(scores, alpha), theirs, scores, alpha)


@settings(max_examples=100)
@given(SCORES, ALPHAS, st.integers(2, 5), st.integers(0, 2**32 - 1))
def test_mondrian_conformal_matches_crepes_per_bin(scores, alpha, n_bins, seed):
    strata = np.random.default_rng(seed).integers(0, n_bins, len(scores))
    ours = mondrian_quantiles(scores, strata, alpha)
    for stratum, q in ours.items():
        theirs = crepes_half_width(scores, alpha, bins=strata, at_bin=stratum)
        assert_same_quantile(q, theirs, scores[strata == stratum], alpha)
