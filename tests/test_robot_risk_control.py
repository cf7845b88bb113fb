"""Risk-controlled anticipation (pingpong.robot.risk_control): the bounds, the Learn-then-Test choice on
synthetic losses of known risk, the gain family's monotonicity, and the re-split summary."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import settings as settings_h
from hypothesis import strategies as st

from pingpong.robot.risk_control import (
    BOUNDS,
    UPPER_BOUNDS,
    RiskSettings,
    binomial_upper_bound,
    exceedance_summary,
    family_controllers,
    gains,
    hoeffding_bentkus_upper_bound,
    risk_control_table,
    select_lambda,
    split_outcome,
)

LAMBDAS = [0.0, 0.2, 0.4, 0.6, 0.8, 1.0]
# excess miss rates over servo of each lambda: (p_plus, p_minus), risk p_plus - p_minus = 0, -0.04, 0.03,
# 0.08, 0.13, 0.2; with epsilon 0.1 lambda 0.6 is the most aggressive safe one and 0.8 is just unsafe
CURVE = [(0.0, 0.0), (0.04, 0.08), (0.10, 0.07), (0.15, 0.07), (0.20, 0.07), (0.26, 0.06)]
RISK = np.array([p - m for p, m in CURVE])


def draw_excess(rng: np.random.Generator, n: int, curve=CURVE) -> np.ndarray:
    """(n, L) excesses in {-1, 0, 1} with P(+1) = p_plus, P(-1) = p_minus per column, one uniform per hit
    shared by the columns (nested rules: a hit that one rule misses, a more aggressive one tends to)."""
    u = rng.random(n)[:, None]
    plus = np.array([p for p, _ in curve])[None, :]
    minus = np.array([m for _, m in curve])[None, :]
    return np.where(u < plus, 1, np.where(u > 1 - minus, -1, 0))


def settings(**overrides) -> RiskSettings:
    values = {"epsilon": 0.1, "delta": 0.1, "family": "step", "lambdas": LAMBDAS, "bound": "binomial",
              "testing": "fixed_sequence", "n_resplits": 20, "stress_controls": [], **overrides}
    return RiskSettings(**values)


@pytest.mark.parametrize("bound", BOUNDS)
@pytest.mark.parametrize("testing", ["fixed_sequence", "bonferroni"])
def test_chosen_lambda_controls_the_risk(bound, testing):
    """Over many calibration sets of 41 hits, the chosen lambda's true risk exceeds epsilon at most a
    delta share of the time (with 3 standard errors of Monte Carlo slack); choosing by the empirical
    risk alone (no bound) exceeds it far more often, so the check can fail."""
    rng = np.random.default_rng(0)
    draws, n, epsilon, delta = 1000, 41, 0.1, 0.1
    chosen, naive = [], []
    for _ in range(draws):
        excess = draw_excess(rng, n)
        chosen.append(select_lambda(excess, epsilon, delta, bound, testing)[0])
        passing = np.flatnonzero(excess.mean(axis=0) <= epsilon)
        naive.append(passing.max())
    violation = np.mean(RISK[chosen] > epsilon)
    slack = 3 * np.sqrt(delta * (1 - delta) / draws)
    assert violation <= delta + slack
    assert np.mean(RISK[naive] > epsilon) > delta + slack
    # and not vacuous: with the default bound and testing some anticipation (lambda >= 0.2, whose risk is
    # negative) is chosen in a third of the draws at 41 hits (Hoeffding-Bentkus never gets there)
    if (bound, testing) == ("binomial", "fixed_sequence"):
        assert np.mean(np.array(chosen) >= 1) > 0.25


@given(st.integers(0, 60), st.integers(0, 60), st.integers(0, 60),
       st.sampled_from([0.01, 0.05, 0.1, 0.2]))
def test_binomial_bound_monotone(n_plus, n_minus, n_zero, delta):
    """More misses than servo (a 0 turned +1) never lowers the bound; a +1 turned -1 never raises it; the
    bound is at least the empirical mean."""
    excess = np.array([1] * n_plus + [-1] * n_minus + [0] * n_zero)
    if len(excess) == 0:
        return
    bound = binomial_upper_bound(excess, delta)
    assert bound >= excess.mean() - 1e-12
    if n_zero:
        worse = np.array([1] * (n_plus + 1) + [-1] * n_minus + [0] * (n_zero - 1))
        assert binomial_upper_bound(worse, delta) >= bound - 1e-12
    if n_plus:
        better = np.array([1] * (n_plus - 1) + [-1] * (n_minus + 1) + [0] * n_zero)
        assert binomial_upper_bound(better, delta) <= bound + 1e-12


@given(st.lists(st.sampled_from([-1, 0, 1]), min_size=1, max_size=80), st.sampled_from([0.05, 0.1, 0.2]))
def test_hoeffding_bentkus_bound(excess, delta):
    """An upper bound of the mean in [-1, 1], that does not fall when a loss rises."""
    excess = np.array(excess)
    bound = hoeffding_bentkus_upper_bound(excess, delta)
    assert excess.mean() - 1e-9 <= bound <= 1
    if (excess < 1).any():
        worse = excess.copy()
        worse[np.flatnonzero(excess < 1)[0]] += 1
        assert hoeffding_bentkus_upper_bound(worse, delta) >= bound - 1e-9


@pytest.mark.parametrize("bound", BOUNDS)
def test_bounds_cover(bound):
    """Each bound lies below the true risk in at most a delta share of samples (Monte Carlo)."""
    rng = np.random.default_rng(1)
    delta = 0.1
    for curve_point in [(0.05, 0.15), (0.1, 0.05), (0.02, 0.0)]:
        risk = curve_point[0] - curve_point[1]
        below = [UPPER_BOUNDS[bound](draw_excess(rng, 41, [curve_point])[:, 0], delta) < risk
                 for _ in range(800)]
        assert np.mean(below) <= delta + 3 * np.sqrt(delta * (1 - delta) / 800)


@given(st.integers(0, 2**32 - 1), st.sampled_from(BOUNDS), st.sampled_from(["fixed_sequence", "bonferroni"]))
def test_choice_monotone_in_epsilon_and_delta(seed, bound, testing):
    """A larger margin or a larger allowed failure probability never chooses a less aggressive lambda."""
    excess = draw_excess(np.random.default_rng(seed), 41)
    chosen = [select_lambda(excess, eps, 0.1, bound, testing)[0] for eps in (0.0, 0.05, 0.1, 0.2, 0.5)]
    assert chosen == sorted(chosen)
    chosen = [select_lambda(excess, 0.1, d, bound, testing)[0] for d in (0.01, 0.05, 0.1, 0.3)]
    assert chosen == sorted(chosen)


def test_no_excess_anywhere_passes_only_above_the_floor():
    """Rules that never differ from servo: their bound is the Clopper-Pearson floor 1 - (delta/2)^(1/n),
    so epsilon below it keeps servo and epsilon above it takes the most aggressive."""
    excess = np.zeros((41, 4), int)
    floor = 1 - 0.05 ** (1 / 41)
    assert select_lambda(excess, floor - 1e-6, 0.1, "binomial")[0] == 0
    assert select_lambda(excess, floor + 1e-6, 0.1, "binomial")[0] == 3


@given(st.lists(st.floats(0, 2), min_size=1, max_size=30), st.lists(st.floats(0, 2), min_size=1, max_size=30))
def test_gain_family_monotone(uncertainty, reference):
    """f_lambda(u): non-decreasing in lambda at every u, non-increasing in u at every lambda, 0 at lambda
    = 0, and for the step family 1 at lambda = 1 on every u within the reference."""
    u = np.array(uncertainty)
    for family in ("step", "uniform"):
        g = gains(family, LAMBDAS, u, np.array(reference))
        assert np.all(np.diff(g, axis=0) >= 0)
        order = np.argsort(u, kind="stable")
        assert np.all(np.diff(g[:, order], axis=1) <= 0)
        assert np.all(g[0] == 0)
    inside = u[u <= max(reference)]
    assert np.all(gains("step", LAMBDAS, inside, np.array(reference))[-1] == 1)


def test_family_controllers_match_the_gains():
    """The controllers apply the family's gains: lambda = 0 is servo, the step's ramp is a step at the
    lambda-quantile, the uniform family's alphas are lambda."""
    from pingpong.robot.evaluate import confidence_ramp

    reference = np.linspace(0.1, 1.0, 10)
    step = family_controllers("step", LAMBDAS, reference)
    assert (step[0].alpha1, step[0].alpha2, step[0].confidence) == (0.0, 0.0, None)
    for controller, gain in zip(step[1:], gains("step", LAMBDAS, reference, reference)[1:], strict=True):
        assert np.array_equal(confidence_ramp(reference, *controller.confidence), gain)
    uniform = family_controllers("uniform", LAMBDAS, None)
    assert [c.alpha1 for c in uniform] == LAMBDAS
    with pytest.raises(ValueError, match="increase from 0 to 1"):
        family_controllers("uniform", [0.0, 0.5], None)


def test_split_outcome_counts():
    """Misses of servo, full anticipation and the chosen rule on the test rows; exceeds when the chosen
    rule misses more than epsilon of the test hits beyond servo."""
    misses = np.zeros((10, 3), bool)  # servo and lambda 0.5 never miss, full anticipation always does
    misses[:, 2] = True
    out = split_outcome(misses, np.arange(5), np.arange(5, 10), [0.0, 0.5, 1.0], settings(epsilon=0.5))
    # lambda 0.5 passes (bound 1 - 0.05^(1/5) = 0.45 <= 0.5), full anticipation fails
    assert out["lambda"] == 0.5
    assert out["calibration_upper_bound_pct"] == pytest.approx(100 * (1 - 0.05 ** 0.2))
    assert (out["servo_misses"], out["anticipatory_misses"], out["risk_controlled_misses"]) == (0, 5, 0)
    assert out["anticipatory_exceeds"] and not out["exceeds"]


def test_exceedance_summary():
    """20 re-splits at delta 0.1 allow 4 exceedances (the 95 % quantile of Binomial(20, 0.1))."""
    assert exceedance_summary(np.zeros(20, bool), 0.1)["allowed_exceedances"] == 4
    summary = exceedance_summary(np.array([True] * 5 + [False] * 15), 0.1)
    assert not summary["bar_met"] and summary["exceedances"] == 5
    assert summary["exceed_rate_ci95_low_pct"] < 25 < summary["exceed_rate_ci95_high_pct"]


def test_risk_control_table_on_synthetic_misses():
    """The table: the dataset's split, the re-splits and one summary row, the summary counting them."""
    rng = np.random.default_rng(3)
    excess = draw_excess(rng, 135)
    servo = rng.random(135) < 0.3
    misses = np.column_stack([servo, *(np.clip(servo + excess[:, k], 0, 1).astype(bool)
                                       for k in range(1, len(LAMBDAS)))])
    is_calibration = np.arange(135) < 41
    table = risk_control_table(misses, is_calibration, LAMBDAS, settings(), np.random.default_rng(0))
    assert list(table["kind"]) == ["dataset split"] + ["re-split"] * 20 + ["summary"]
    assert table["exceeds"].iloc[-1] == table["exceeds"].iloc[1:-1].sum()
    assert (table["n_calibration"].iloc[:-1] == 41).all()


def test_stressed_predictions():
    """mirrored negates every strike x and keeps the uncertainties; shuffled permutes whole predictions."""
    from pingpong.robot.evaluate import Prediction
    from pingpong.robot.risk_control import stressed_predictions

    frames = np.array([-10, 0])
    predictions = [Prediction(frames, np.array([k, k + 0.5]), np.array([0.1 * k, 0.2])) for k in range(6)]
    mirrored = stressed_predictions(predictions, "mirrored")
    assert all(np.array_equal(m.strike_x, -p.strike_x) and m.uncertainty is p.uncertainty
               for m, p in zip(mirrored, predictions, strict=True))
    shuffled = stressed_predictions(predictions, "shuffled", np.random.default_rng(0))
    assert sorted(id(p) for p in shuffled) == sorted(id(p) for p in predictions)
    assert [id(p) for p in shuffled] != [id(p) for p in predictions]
    with pytest.raises(ValueError, match="stress control"):
        stressed_predictions(predictions, "flipped")


@settings_h(max_examples=25)
@given(st.lists(st.tuples(st.floats(0, 0.4), st.floats(0, 0.4)), min_size=2, max_size=6),
       st.sampled_from([0.05, 0.1, 0.2]), st.integers(30, 120))
def test_any_risk_curve_is_controlled(curve, epsilon, n):
    """Any family of rules (random excess-miss curves over lambda, drawn by hypothesis; lambda = 0 is servo):
    over 400 calibration sets the chosen rule's true risk exceeds epsilon in at most delta (+3 SE)."""
    curve = [(0.0, 0.0), *curve]
    risk = np.array([p - m for p, m in curve])
    rng = np.random.default_rng(len(curve) * 1000 + n)
    draws, delta = 400, 0.1
    chosen = [select_lambda(draw_excess(rng, n, curve), epsilon, delta, "binomial")[0] for _ in range(draws)]
    assert np.mean(risk[chosen] > epsilon) <= delta + 3 * np.sqrt(delta * (1 - delta) / draws)
