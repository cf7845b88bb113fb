"""Uncertainty estimators and metrics: conformal coverage within its finite-sample bounds on synthetic
exchangeable data, rank metrics against hand-computed cases, and the estimators wired on a toy dataset."""

import json
import math

import numpy as np
import pandas as pd
import pytest
from conftest import coverage_bounds
from hypothesis import given
from hypothesis import strategies as st

from pingpong.common.artifacts import Provenance
from pingpong.learning.models import FRAMES_BEFORE_HIT
from pingpong.uncertainty.conformal import (
    conformal_quantile,
    cqr_scores,
    mondrian_quantiles,
    normalised_scores,
)
from pingpong.uncertainty.features import frame_features
from pingpong.uncertainty.fit import (
    estimator_tables,
    fit_estimators,
    fitted_record,
    frame_rows,
    restore_estimators,
)
from pingpong.uncertainty.knn import fit_knn, nearest_rows, predict_knn
from pingpong.uncertainty.metrics import (
    ause,
    coverage_by_width,
    ence,
    interval_metrics,
    sparsification,
    spearman,
    winkler_score,
    within_frames,
)
from pingpong.uncertainty.names import ESTIMATORS
from pingpong.uncertainty.quantile_heads import fit_quantile_heads, predict_quantiles
from pingpong.uncertainty.registry import REGISTRY, Band, Estimator, Hits, UncertaintySettings, register
from pingpong.uncertainty.time_to_hit import fit_trend, trend

ALPHA = 0.1
TRIALS = 400  # calibration draws; each trial's coverage is measured on its own test points


def test_split_conformal_coverage_within_the_finite_sample_bound():
    rng = np.random.default_rng(0)
    n_cal, n_test = 50, 200
    errors = np.abs(rng.standard_t(3, size=(TRIALS, n_cal + n_test)))  # heavy-tailed |y - y_hat|
    q = np.array([conformal_quantile(e[:n_cal], ALPHA) for e in errors])
    covered = (errors[:, n_cal:] <= q[:, None]).mean(axis=1)
    low, high = coverage_bounds(n_cal, covered, ALPHA)
    assert low <= covered.mean() <= high
    # with one score per hit the quantile is the ceil((1 - alpha)(n + 1))-th smallest
    assert q[0] == np.sort(errors[0, :n_cal])[math.ceil((1 - ALPHA) * (n_cal + 1)) - 1]


def test_hit_grouped_conformal_covers_dependent_frames():
    """30 strongly dependent frames per hit (a random hit effect): calibrating by hit keeps
    E[share of a test hit's frames covered] >= 1 - alpha with 20 calibration hits (conformal.py)."""
    rng = np.random.default_rng(1)
    n_cal, n_test, k = 20, 40, 30
    scale = rng.lognormal(0, 0.8, size=(TRIALS, n_cal + n_test, 1))  # per-hit difficulty
    errors = scale * np.abs(rng.normal(size=(TRIALS, n_cal + n_test, k)))
    groups = np.repeat(np.arange(n_cal), k)
    q = np.array([conformal_quantile(e[:n_cal].ravel(), ALPHA, groups) for e in errors])
    covered = (errors[:, n_cal:] <= q[:, None, None]).mean(axis=(1, 2))
    assert covered.mean() >= 1 - ALPHA - 4 * covered.std() / math.sqrt(TRIALS)
    assert covered.mean() <= 1 - ALPHA + 0.05  # not trivially wide
    with pytest.raises(ValueError):
        conformal_quantile([0.1, np.nan], ALPHA)
    assert conformal_quantile(np.ones(60), ALPHA, np.repeat(np.arange(2), 30)) == np.inf  # 2 hits < 9


def test_mondrian_covers_every_frame_where_one_width_does_not():
    rng = np.random.default_rng(2)
    n_cal, n_test = 40, 100
    frame_scale = np.array([0.05, 0.2, 0.8])  # error grows with the time before the hit
    cal = np.abs(rng.normal(size=(TRIALS, 3, n_cal))) * frame_scale[:, None]
    test = np.abs(rng.normal(size=(TRIALS, 3, n_test))) * frame_scale[:, None]
    strata = np.repeat(np.arange(3), n_cal)
    per_frame, pooled = [], []
    for c, t in zip(cal, test, strict=True):
        qs = mondrian_quantiles(c.ravel(), strata, ALPHA)
        per_frame.append([(t[f] <= qs[f]).mean() for f in range(3)])
        pooled.append((t <= conformal_quantile(c.ravel(), ALPHA)).mean(axis=1))
    per_frame, pooled = np.array(per_frame), np.array(pooled)
    for f in range(3):
        low, high = coverage_bounds(n_cal, per_frame[:, f], ALPHA)
        assert low <= per_frame[:, f].mean() <= high
    assert pooled[:, 2].mean() < 0.8  # one width under-covers the hardest frame


def test_normalised_and_cqr_coverage_within_the_bound_and_adaptive_widths():
    rng = np.random.default_rng(3)
    n_cal, n_test = 50, 200
    sigma = rng.uniform(0.05, 0.5, size=(TRIALS, n_cal + n_test))  # a known difficulty
    y = sigma * rng.normal(size=sigma.shape)  # residual around y_hat = 0
    norm_cov, cqr_cov, widths = [], [], []
    for s, r in zip(sigma, y, strict=True):
        q = conformal_quantile(normalised_scores(np.abs(r[:n_cal]), s[:n_cal]), ALPHA)
        norm_cov.append(np.mean(np.abs(r[n_cal:]) <= q * s[n_cal:]))
        widths.append(2 * q * s[n_cal:])
        lo, hi = -0.5 * s, 0.5 * s  # too-narrow quantile heads: CQR widens them by q
        q_cqr = conformal_quantile(cqr_scores(r[:n_cal], lo[:n_cal], hi[:n_cal]), ALPHA)
        cqr_cov.append(np.mean((lo[n_cal:] - q_cqr <= r[n_cal:]) & (r[n_cal:] <= hi[n_cal:] + q_cqr)))
    for covered in (np.array(norm_cov), np.array(cqr_cov)):
        low, high = coverage_bounds(n_cal, covered, ALPHA)
        assert low <= covered.mean() <= high
    metrics = interval_metrics(np.zeros(n_test), -widths[0] / 2, widths[0] / 2)
    assert metrics["width_cv"] > 0.3 and metrics["coverage"] == 1.0


def test_quantile_heads_learn_heteroscedastic_quantiles():
    rng = np.random.default_rng(4)
    x = rng.uniform(0, 1, size=(2000, 1))
    y = (0.05 + 0.3 * x[:, 0]) * rng.normal(size=2000)
    heads = fit_quantile_heads(x, y, (0.05, 0.95), rng, epochs=400)
    q = predict_quantiles(heads, np.array([[0.1], [0.9]]))
    expected = 1.645 * (0.05 + 0.3 * np.array([0.1, 0.9]))
    assert np.allclose(q[:, 1], expected, rtol=0.25) and np.allclose(q[:, 0], -expected, rtol=0.25)


def test_error_head_learns_which_hits_are_hard(tmp_path):
    """Errors 10x larger on hits whose channel 0 is high: the head, trained on 150 hits, ranks 150
    unseen hits by that (within-frame Spearman > 0.45; knowing which hits are hard gives 0.75, a
    constant 0) and round-trips through its artifact."""
    from pingpong.common.artifacts import Provenance
    from pingpong.uncertainty import error_head as head

    rng = np.random.default_rng(11)
    n = 300
    X = rng.normal(size=(n, 40, 39)).astype(np.float32)
    k = len(FRAMES_BEFORE_HIT)  # the prediction frames t = -30 .. 0
    hard = X[:, -k:, 0].mean(axis=1) > 0  # visible over the prediction frames
    X[:, -k:, 0] += np.where(hard, 1.0, -1.0)[:, None]
    errors = np.abs(rng.normal(size=(n, k))) * np.where(hard, 0.5, 0.05)[:, None]
    pred = rng.normal(0, 0.3, size=(n, k))
    net = head.fit_error_head(X[:150], pred[:150], errors[:150], rng, epochs=30)
    u = head.predict_error(net, X[150:], pred[150:])
    frames = np.tile(FRAMES_BEFORE_HIT, 150)
    assert (u > 0).all() and within_frames(spearman, u.ravel(), errors[150:].ravel(), frames) > 0.45
    head.save(net, tmp_path / "head", Provenance.of("uncertainty"))
    assert np.allclose(head.predict_error(head.load(tmp_path / "head"), X[150:], pred[150:]), u)
    with pytest.raises(ValueError, match="finite"):
        head.fit_error_head(X[:10], pred[:10], np.full((10, k), np.nan), rng)


def test_spearman_and_within_frame_hand_computed():
    assert spearman([1, 2, 3, 4], [1, 3, 2, 4]) == pytest.approx(1 - 6 * 2 / (4 * 15))  # sum d^2 = 2
    assert math.isnan(spearman([2, 2, 2, 2], [1, 3, 2, 4]))  # constant: no ranking
    frames = np.array([1, 1, 1, 2, 2, 2])
    u = np.array([1, 2, 3, 1, 2, 3])
    e = np.array([1, 2, 3, 3, 2, 1])
    assert within_frames(spearman, u, e, frames) == pytest.approx(0.0)  # +1 and -1
    assert math.isnan(within_frames(spearman, frames, e, frames))  # time alone says nothing within a frame


def test_sparsification_and_ause_hand_computed():
    e = np.array([1.0, 2.0, 3.0, 4.0])
    fractions = np.array([0.0, 0.25, 0.5, 0.75])
    curve, oracle = sparsification(4 - e, e, fractions)  # the worst ranking: most sure of the largest errors
    assert np.allclose(curve, np.array([2.5, 3.0, 3.5, 4.0]) / 2.5)
    assert np.allclose(oracle, np.array([2.5, 2.0, 1.5, 1.0]) / 2.5)
    assert ause(4 - e, e, fractions) == pytest.approx(0.25 * (0.5 + 1.5 + 2.5) / 2.5)
    assert ause(e, e) == 0.0
    flat, _ = sparsification(np.ones(4), e, fractions)  # ties count at their expected value
    assert np.allclose(flat, 1.0)
    rng = np.random.default_rng(5)
    errors = rng.exponential(size=4000)
    assert ause(rng.uniform(size=4000), errors) > 0.2
    assert ause(errors + rng.normal(0, 0.1, 4000), errors) < 0.1


def test_ence_winkler_and_width_coverage_hand_computed():
    # two bins: predicted std 1 with residuals of RMS 1 (calibrated), std 2 with RMS 1 (half too wide)
    std = np.array([1.0, 1.0, 2.0, 2.0])
    assert ence(std, np.array([1.0, -1.0, 1.0, -1.0]), n_bins=2) == pytest.approx((0 + 0.5) / 2)
    rng = np.random.default_rng(3)
    s = rng.uniform(0.1, 2.0, 20000)
    assert ence(s, s * rng.standard_normal(s.size)) < 0.05  # Gaussian residuals of the stated std
    assert ence(s, 2 * s * rng.standard_normal(s.size)) == pytest.approx(1.0, abs=0.05)  # twice too narrow
    y, lower, upper = np.array([0.0, 5.0, -3.0]), np.array([-1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0])
    # widths 2 each; y = 5 lies 4 above, y = -3 lies 2 below: 2 + (2 / 0.1) * (0, 4, 2) on average
    assert winkler_score(y, lower, upper, 0.1) == pytest.approx(2 + 20 * 6 / 3)
    # widths 2, 2, 2, 10: the narrow pair (rows 0, 1) covers, the wide pair (rows 3 and 2) covers row 2 only
    assert np.allclose(coverage_by_width(np.array([0.0, 0.0, 3.0, 3.0]), np.array([-1, -1, -5, -1.0]),
                                         np.array([1, 1, 5, 1.0]), n_bins=2), [1.0, 0.5])


@given(st.lists(st.tuples(st.floats(-5, 5), st.floats(0, 3), st.floats(0, 3)), min_size=1, max_size=40),
       st.floats(0.01, 0.5))
def test_winkler_score_is_at_least_the_width_and_equals_it_when_all_cover(rows, alpha):
    y, below, above = np.array(rows).T
    lower, upper = -below, above
    width = float(np.mean(upper - lower))
    assert winkler_score(y, lower, upper, alpha) >= width - 1e-9
    inside = np.clip(y, lower, upper)
    assert winkler_score(inside, lower, upper, alpha) == pytest.approx(width)


@given(st.lists(st.floats(0, 10), min_size=1, max_size=40), st.floats(0.01, 0.98), st.floats(0.01, 0.98))
def test_conformal_quantile_monotone_in_alpha_and_non_negative(scores, a, b):
    low, high = sorted((a, b))
    assert conformal_quantile(scores, high) <= conformal_quantile(scores, low)
    assert conformal_quantile(scores, high) >= 0


@given(st.lists(st.tuples(st.floats(0, 5), st.floats(0, 5)), min_size=2, max_size=60))
def test_ause_is_non_negative(pairs):
    u, e = np.array(pairs).T
    assert ause(u, e) >= -1e-12


@pytest.mark.parametrize("dims", [1, 79])
def test_nearest_rows_are_scipys_cKDTree_neighbours(dims, monkeypatch):
    from scipy.spatial import cKDTree

    from pingpong.uncertainty import knn

    monkeypatch.setattr(knn, "BLOCK_DISTANCES", 900 * 64)  # blocks of 64 query rows, the last one short
    rng = np.random.default_rng(dims)
    # rows with low-dimensional structure, as the frame features have: no near ties to break differently
    reference, queries = (rng.normal(size=(n, min(dims, 5))) @ rng.normal(size=(min(dims, 5), dims))
                          + 0.3 * rng.normal(size=(n, dims)) for n in (900, 700))
    distance, expected = cKDTree(reference).query(queries, k=7)
    found = nearest_rows(reference, queries, 7)
    np.testing.assert_array_equal(found, expected)
    np.testing.assert_allclose(np.linalg.norm(queries[:, None] - reference[found], axis=2), distance,
                               rtol=1e-12)


def test_knn_time_trend_and_features():
    model = fit_knn(np.array([[0.0], [1.0], [10.0]]), np.array([0.1, 0.2, 0.9]), k=1)
    assert np.allclose(predict_knn(model, np.array([[0.2], [9.0]])), [0.1, 0.9])
    frames = np.tile(np.arange(1, 31), 3)
    intercept, slope = fit_trend(frames, 0.05 + 0.01 * frames)
    assert (intercept, slope) == (pytest.approx(0.05), pytest.approx(0.01))
    assert trend(0.05, -0.01, [1, 10]).tolist() == [pytest.approx(0.04), 0.0]
    X = np.random.default_rng(6).normal(size=(2, 40, 39))
    F = frame_features(X, FRAMES_BEFORE_HIT)
    k = len(FRAMES_BEFORE_HIT)
    j = 5  # row n * k + j is FRAMES_BEFORE_HIT[j] frames before the hit
    f = FRAMES_BEFORE_HIT[j]
    assert F.shape == (2 * k, 79) and np.allclose(F[k + j, :39], X[1, 39 - f])
    assert np.allclose(F[k + j, 39:78], 100 * (X[1, 39 - f] - X[1, 38 - f])) and F[k + j, 78] == f


SETTINGS = UncertaintySettings(coverage=0.9, knn_k=5, quantile_hidden=32, quantile_epochs=20,
                               error_head_hidden=16, error_head_epochs=2, hetero_hidden=8, hetero_epochs=2)


K = len(FRAMES_BEFORE_HIT)  # predictions per hit


def toy_hits(n=60, seed=7) -> Hits:
    """n hits (half train, a quarter each calibration and test) with random inputs and predictions."""
    rng = np.random.default_rng(seed)
    split = np.array(["train"] * (n // 2) + ["calibration"] * (n // 4) + ["test"] * (n - n // 2 - n // 4))
    dataset = pd.DataFrame({"session": "s00", "rally": np.arange(n), "hit": np.arange(n), "split": split,
                            "strike_x": rng.uniform(-0.7, 0.7, n)})
    X = rng.normal(size=(n, 40, 39))
    rows = frame_rows(dataset, pd.DataFrame({
        "model": "final", "session": "s00", "rally": np.repeat(np.arange(n), K),
        "hit": np.repeat(np.arange(n), K), "frames_before_hit": np.tile(FRAMES_BEFORE_HIT, n),
        "a1": 0.0, "a2": 0.0, "b": 0.0, "strike_x_pred": rng.normal(0, 0.3, K * n)}))
    ensemble = rows["strike_x_pred"].to_numpy() + rng.normal(0, 0.05, size=(3, len(rows)))
    return Hits(rows, frame_features(X, FRAMES_BEFORE_HIT), X, ensemble)


def test_fit_estimators_on_a_toy_dataset():
    hits = toy_hits()
    fitted = fit_estimators(hits, SETTINGS, np.random.default_rng(7))
    tables, record = estimator_tables(hits, fitted), fitted_record(hits, fitted, SETTINGS.coverage, {})
    assert list(tables) == list(ESTIMATORS) and fitted["knn"].model.k == 5 and record["knn"] == {"k": 5}
    assert -1 <= record["diagnostics"]["member_error_spearman_within_frame"] <= 1
    for name, table in tables.items():
        assert len(table) == 30 * K and set(table["split"]) == {"calibration", "test"}
        assert (table["uncertainty"] >= 0).all(), name
        interval = table["lower"].notna()
        assert (table.loc[interval, "lower"] <= table.loc[interval, "upper"]).all()
        assert interval.all() == (name not in ("ensemble", "knn", "time_to_hit", "error_head"))
    assert np.isfinite(record["conformal"]["quantile"])  # 15 calibration hits >= 9


def test_estimators_restored_from_their_artifacts_apply_alike(tmp_path):
    hits = toy_hits()
    fitted = fit_estimators(hits, SETTINGS, np.random.default_rng(3))
    stems = {}
    for estimator in fitted.values():
        if estimator.model_file:
            stems[estimator.model_file] = str(tmp_path / estimator.model_file)
            estimator.save_model(stems[estimator.model_file], Provenance.of("test"))
    record = json.loads(json.dumps(fitted_record(hits, fitted, SETTINGS.coverage, {})))  # through JSON
    restored = restore_estimators(record, SETTINGS, stems)
    assert list(restored) == list(fitted)
    for name, table in estimator_tables(hits, restored).items():
        pd.testing.assert_frame_equal(table, estimator_tables(hits, fitted)[name], check_exact=False,
                                      rtol=1e-6, obj=name)


class HalfTheError(Estimator):
    """A toy estimator beyond the registered ones: half the ensemble spread plus the k-NN error."""

    name = "toy_half"

    def fit(self, hits, fitted, rng):
        self.parts = fitted["ensemble"], fitted["knn"]

    def apply(self, hits):
        return Band(0.5 * sum(p.apply(hits).uncertainty for p in self.parts))


def test_a_registered_toy_estimator_reaches_the_uncertainty_table():
    from pingpong.reports.uncertainty import summary_table

    register(HalfTheError)
    try:
        hits = toy_hits()
        fitted = fit_estimators(hits, SETTINGS, np.random.default_rng(5))
        summary = summary_table(estimator_tables(hits, fitted))
    finally:
        REGISTRY.pop("toy_half")
    row = summary.set_index("estimator").loc["toy_half"]
    assert not row["paper"] and np.isfinite(row["spearman_within_frame"])
    assert list(summary["estimator"]) == [*ESTIMATORS, "toy_half"]
    with pytest.raises(ValueError, match="'ensemble' is already registered"):
        register(type("Again", (Estimator,), {"name": "ensemble"}))


class _KnownHetero:
    """A stand-in for the fitted heteroscedastic head: every row's true noise std, no bias."""

    name = "hetero"

    def __init__(self, std):
        self.std = std

    def mean_std(self, hits):
        return hits.pred, self.std


N_CAL_HITS = 41  # the calibration hits of the default run (README; 76 when it had 21 rallies a session)
FRAMES_USED = np.array([20, 10, 1])  # a few frames before the hit keep the trials fast


def _exchangeable_hits(rng, n_train=40, n_test=60, n_cal=N_CAL_HITS):
    """Training, calibration and test hits of one draw: residuals N(0, std) with a per-hit difficulty and
    a per-frame scale, the ensemble's spread a noisy guess of the std, the ball's speed random."""
    n = n_train + n_cal + n_test
    k = len(FRAMES_USED)
    std = (rng.lognormal(0, 0.6, (n, 1)) * np.array([0.3, 0.2, 0.1])).ravel()
    pred = rng.normal(0, 0.3, n * k)
    y = pred + std * rng.standard_normal(n * k)
    split = np.repeat(np.select([np.arange(n) < n_train, np.arange(n) < n_train + n_cal],
                                ["train", "calibration"], "test"), k)
    rows = pd.DataFrame({"split": split, "hit_index": np.repeat(np.arange(n), k),
                         "frames_before_hit": np.tile(FRAMES_USED, n), "strike_x": y, "strike_x_pred": pred,
                         "abs_error": np.abs(y - pred)})
    features = np.zeros((n * k, 2 * 39 + 1))
    features[:, 75] = rng.uniform(3, 12, n * k)  # the ball's speed along x: mondrian_speed's context
    spread = std * rng.lognormal(0, 0.3, n * k)
    return Hits(rows, features, np.zeros((n, 1, 39)), np.stack([pred - spread, pred + spread])), std


@pytest.mark.parametrize(("n_cal", "n_bins"), [(10, 1), (35, 1), (36, 2), (41, 2), (54, 3), (300, 3)])
def test_mondrian_speed_bins_follow_the_calibration_size(n_cal, n_bins):
    """As many speed bins as leave the mean cell twice the 9 hits a finite 90 % quantile needs, at most 3;
    every cell's quantile finite at the default run's size."""
    from pingpong.uncertainty import estimators as est

    hits, _ = _exchangeable_hits(np.random.default_rng(5), n_cal=n_cal)
    estimator = est.MondrianSpeed(SETTINGS)
    estimator.fit(hits, {}, np.random.default_rng(0))
    assert {len(e) + 1 for e in estimator.edges.values()} == {n_bins}
    if n_cal == 41:  # the default run's: its cells hold ~20 hits, 9 lies 3.6 standard deviations below
        assert np.isfinite(list(estimator.by_cell.values())).all()


@pytest.mark.parametrize("name", ["conformal", "mondrian", "ensemble_time", "mondrian_speed",
                                  "normalised_ensemble", "normalised_hetero", "cqr_hetero", "clear"])
def test_every_conformal_estimator_covers_within_the_finite_sample_bound(name):
    """The registered estimators themselves (the learned parts replaced by known values) over repeated
    calibration draws of the default run's size: per frame (pooled over frames for the two with one
    quantile for all frames), 1 - alpha <= E[coverage] <= 1 - alpha +
    1/(n + 1), n the calibration hits of the estimator's quantile (half for CLEAR's scale; for the speed
    bins, halves at this size, whose cells hold ~20 calibration hits: the bound is taken at 15, two
    binomial standard deviations below), widened by 4 standard errors over the trials."""
    from pingpong.uncertainty import estimators as est

    rng = np.random.default_rng(11)
    per_frame = name not in ("conformal", "normalised_ensemble")  # those two: one quantile for all frames
    trials, coverage = 150, {f: [] for f in (FRAMES_USED if per_frame else ["all"])}
    for _ in range(trials):
        hits, std = _exchangeable_hits(rng)
        fitted = {"ensemble": est.Ensemble(SETTINGS), "hetero": _KnownHetero(std)}
        estimator = REGISTRY[name](SETTINGS)
        estimator.fit(hits, fitted, rng)
        band = estimator.apply(hits)
        inside = (band.lower <= hits.y) & (hits.y <= band.upper)
        for f in coverage:
            coverage[f].append(inside[(hits.split == "test") & ((hits.frames == f) | (f == "all"))].mean())
    n_cal = {"clear": N_CAL_HITS - N_CAL_HITS // 2, "mondrian_speed": 15}.get(name, N_CAL_HITS)
    for f, share in coverage.items():
        share = np.array(share)
        low, high = coverage_bounds(n_cal, share, ALPHA)
        assert low <= share.mean() <= high, (name, f)
