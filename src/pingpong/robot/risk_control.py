"""Anticipation with a guarantee (beyond the paper): each prediction's early gain alpha chosen from a
calibrated uncertainty so that the miss rate with anticipation exceeds visual servoing's by at most epsilon,
with probability at least 1 - delta over the calibration hits.

The family of gain rules alpha = f_lambda(u), lambda in a grid from 0 (no anticipation: servo) to 1 (full
anticipation), is monotone: for every uncertainty u the gain does not decrease with lambda, and for every
lambda it does not increase with u.
  - step: alpha = 1 where u <= the lambda-quantile of the reference uncertainties, else 0 (lambda = 0: none);
  - uniform: alpha = lambda whatever u (the control: is the uncertainty what helps?).
The reference uncertainties are those of every pooled hit's used prediction frames (outcomes unseen):
a function of the pool, not of the split, so every calibration/test re-split shares one family. The
re-splits reuse the one fitted estimator, whose own calibration saw the dataset's calibration hits: their
uncertainties are in-sample for it wherever a re-split puts them among the test hits.

The loss of a hit under lambda is its excess miss over servo, miss(lambda) - miss(servo) in {-1, 0, 1}; the
risk R(lambda) is its mean. Learn then Test (Angelopoulos, Bates, Candes, Jordan and Lei 2021, "Learn then
Test: calibrating predictive algorithms to achieve risk control", Sec. 3; the fixed-sequence procedure of
its Sec. 4.1) turns an upper confidence bound of R into a choice: the lambdas are tested from the least to
the most aggressive, each null R(lambda) > epsilon rejected when its (1 - delta) upper bound is <= epsilon,
stopping at the first not rejected; the most aggressive rejected lambda is chosen (fixed-sequence testing
controls the family-wise error at delta, so P(R(chosen) > epsilon) <= delta), lambda = 0 if none is.
lambda = 0 is servo itself (zero loss on every hit) and needs no test. Upper bounds:
  - binomial: R = pi (2 q - 1), pi the share of hits where lambda and servo differ (discordant), q the share
    of those that lambda misses; Clopper-Pearson upper bounds of pi and (given the discordant count) of q,
    each at delta / 2 (a union bound). Tight where few hits differ, which the near-servo lambdas have.
  - hoeffding_bentkus: the Hoeffding-Bentkus bound of Bates, Angelopoulos, Lei, Malik and Jordan 2021
    ("Distribution-free, risk-controlling prediction sets", Sec. 3.1, Prop. 3) on the loss mapped to
    [0, 1], (excess + 1) / 2; loose where most losses are 0.
"""

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.stats import beta, binom

from pingpong.common.config import Settings
from pingpong.common.seeding import rng_for
from pingpong.robot.controllers import CONTROLLERS, Controller
from pingpong.robot.evaluate import Prediction, SimSettings, hit_predictions, simulate_hits, used_predictions
from pingpong.robot.flights import hit_flights

NAME = "risk_controlled"
FAMILIES = ("step", "uniform")
BOUNDS = ("binomial", "hoeffding_bentkus")
STRESS_CONTROLS = ("mirrored", "shuffled")
TESTINGS = ("fixed_sequence", "bonferroni")


@dataclass(frozen=True)
class RiskSettings(Settings):
    """config robot.risk_control (the schema says what each means)."""

    epsilon: float
    delta: float
    family: str
    lambdas: list[float]
    bound: str
    testing: str
    n_resplits: int
    stress_controls: list[str]


def check_lambdas(lambdas) -> np.ndarray:
    """The lambda grid: increasing, from 0 (servo) to 1 (full anticipation)."""
    grid = np.asarray(lambdas, float)
    if len(grid) < 2 or grid[0] != 0 or grid[-1] != 1 or np.any(np.diff(grid) <= 0):
        raise ValueError(f"robot.risk_control.lambdas must increase from 0 to 1, got {list(lambdas)}")
    return grid


def step_thresholds(lambdas, reference: np.ndarray) -> np.ndarray:
    """Uncertainty threshold (m) of each lambda of the step family: -inf at 0, else the lambda-quantile of
    the finite reference uncertainties."""
    reference = np.asarray(reference, float)
    reference = reference[np.isfinite(reference)]
    if len(reference) == 0:
        raise ValueError("the step family needs finite uncertainties; the configured estimator gave none")
    grid = check_lambdas(lambdas)
    return np.where(grid > 0, np.quantile(reference, grid), -np.inf)


def gains(family: str, lambdas, uncertainty: np.ndarray, reference: np.ndarray | None = None) -> np.ndarray:
    """f_lambda(u): gains (L, U) of every lambda at every uncertainty."""
    grid, u = check_lambdas(lambdas), np.asarray(uncertainty, float)
    if family == "uniform":
        return np.repeat(grid[:, None], len(u), axis=1)
    if family == "step":
        return (u[None, :] <= step_thresholds(grid, reference)[:, None]).astype(float)
    raise ValueError(f"unknown gain family '{family}'; expected one of {FAMILIES}")


def family_controllers(family: str, lambdas, reference: np.ndarray | None) -> list[Controller]:
    """The gain rules as controllers (evaluate.step_alphas applies them before the first servo goal): the
    step family as a confidence ramp that is a step at the threshold, the uniform one as alpha1 = alpha2 =
    lambda."""
    grid = check_lambdas(lambdas)
    if family == "uniform":
        return [Controller(NAME, float(g), float(g)) for g in grid]
    if family == "step":
        return [Controller(NAME) if not np.isfinite(t) else Controller(NAME, 1.0, 1.0, confidence=(t, t))
                for t in map(float, step_thresholds(grid, reference))]
    raise ValueError(f"unknown gain family '{family}'; expected one of {FAMILIES}")


def clopper_pearson_upper(k: int, n: int, alpha: float) -> float:
    """One-sided (1 - alpha) Clopper-Pearson upper bound of a binomial proportion (1 for n = 0)."""
    return 1.0 if k >= n else float(beta.ppf(1 - alpha, k + 1, n - k))


def binomial_upper_bound(excess: np.ndarray, delta: float) -> float:
    """(1 - delta) upper bound of the mean of excess in {-1, 0, 1} (module docstring, 'binomial')."""
    excess = np.asarray(excess)
    n_plus, n_minus = int(np.sum(excess > 0)), int(np.sum(excess < 0))
    discordant = n_plus + n_minus
    pi_upper = clopper_pearson_upper(discordant, len(excess), delta / 2)
    q_upper = clopper_pearson_upper(n_plus, discordant, delta / 2)
    return pi_upper * max(2 * q_upper - 1, 0.0)


def hoeffding_bentkus_p(mean_loss: float, n: int, level) -> np.ndarray:
    """p-values of the nulls 'risk > level' (level: array) for n losses in [0, 1] of mean mean_loss (Bates
    et al. 2021, Prop. 3: the smaller of Hoeffding's and Bentkus's)."""
    level = np.asarray(level, float)
    a = np.minimum(mean_loss, level)
    with np.errstate(divide="ignore", invalid="ignore"):
        h1 = (np.where(a > 0, a * np.log(a / level), 0.0)
              + np.where(a < 1, (1 - a) * np.log((1 - a) / (1 - level)), np.inf))
    hoeffding = np.exp(-n * h1)
    bentkus = np.e * binom.cdf(np.ceil(n * mean_loss), n, level)
    return np.minimum(np.minimum(hoeffding, bentkus), 1.0)


HB_LEVELS = 4000  # grid of the bound's search; the bound is the grid level above the exact one


def hoeffding_bentkus_upper_bound(excess: np.ndarray, delta: float) -> float:
    """(1 - delta) upper bound of the mean of excess in [-1, 1]: the smallest risk level above which the
    Hoeffding-Bentkus test of the [0, 1]-mapped losses rejects 'risk > level' at delta (its p-value falls
    as the level rises above the mean loss), searched on a grid and rounded up (conservative)."""
    loss = (np.asarray(excess, float) + 1) / 2
    n, mean = len(loss), float(loss.mean())
    levels = np.linspace(mean, 1, HB_LEVELS + 1)[1:-1]
    rejected = np.flatnonzero(hoeffding_bentkus_p(mean, n, levels) <= delta)
    return 1.0 if len(rejected) == 0 else float(2 * levels[rejected[0]] - 1)


UPPER_BOUNDS = {"binomial": binomial_upper_bound, "hoeffding_bentkus": hoeffding_bentkus_upper_bound}


def select_lambda(excess: np.ndarray, epsilon: float, delta: float, bound: str,
                  testing: str = "fixed_sequence") -> tuple[int, np.ndarray]:
    """(index of the chosen lambda, upper bounds (L,) of the tested ones, NaN where untested).

    excess (n, L): each calibration hit's excess miss over servo under each lambda, column 0 being servo
    itself (lambda = 0, untested). fixed_sequence: columns 1, 2, ... tested in order at delta each, stopping
    at the first not rejected (module docstring); bonferroni: every column tested at delta / (L - 1), the
    most aggressive rejected one chosen. Either keeps P(R(chosen) > epsilon) <= delta."""
    excess = np.asarray(excess)
    upper = UPPER_BOUNDS[bound]
    n_tests = excess.shape[1] - 1
    level = {"fixed_sequence": delta, "bonferroni": delta / max(n_tests, 1)}[testing]
    bounds = np.full(excess.shape[1], np.nan)
    chosen = 0
    for k in range(1, excess.shape[1]):
        bounds[k] = upper(excess[:, k], level) if len(excess) else 1.0
        if bounds[k] <= epsilon:
            chosen = k
        elif testing == "fixed_sequence":
            break
    return chosen, bounds


def split_outcome(misses: np.ndarray, calibration: np.ndarray, test: np.ndarray, lambdas,
                  settings: RiskSettings) -> dict:
    """One calibration/test split of the pooled hits: lambda chosen on calibration, misses on test.

    misses (n, L) bool: every pooled hit's miss under each lambda (column 0 servo, the last full
    anticipation); calibration, test: row indices."""
    misses = np.asarray(misses, bool)
    excess = misses.astype(int) - misses[:, :1].astype(int)
    chosen, bounds = select_lambda(excess[calibration], settings.epsilon, settings.delta, settings.bound,
                                   settings.testing)
    test_misses = misses[test]
    n_test = max(len(test), 1)
    servo, anticipatory, chosen_misses = (int(test_misses[:, k].sum()) for k in (0, -1, chosen))
    return {"n_calibration": len(calibration), "n_test": len(test), "lambda": float(lambdas[chosen]),
            "lambda_index": chosen, "calibration_upper_bound_pct": 100 * bounds[chosen] if chosen else 0.0,
            "servo_misses": servo, "anticipatory_misses": anticipatory,
            "risk_controlled_misses": chosen_misses,
            "servo_miss_pct": 100 * servo / n_test, "anticipatory_miss_pct": 100 * anticipatory / n_test,
            "risk_controlled_miss_pct": 100 * chosen_misses / n_test,
            "excess_pct": 100 * (chosen_misses - servo) / n_test, "epsilon_pct": 100 * settings.epsilon,
            "exceeds": bool(chosen_misses - servo > settings.epsilon * len(test)),
            "anticipatory_exceeds": bool(anticipatory - servo > settings.epsilon * len(test))}


def resplit_outcomes(misses: np.ndarray, n_calibration: int, lambdas, settings: RiskSettings,
                     rng: np.random.Generator) -> pd.DataFrame:
    """split_outcome over settings.n_resplits random splits of the pooled hits (n_calibration of them
    calibrate, the rest test)."""
    rows = []
    for k in range(settings.n_resplits):
        order = rng.permutation(len(misses))
        outcome = split_outcome(misses, order[:n_calibration], order[n_calibration:], lambdas, settings)
        rows.append({"split": f"resplit {k + 1}", **outcome})
    return pd.DataFrame(rows)


def exceedance_summary(exceeds: np.ndarray, delta: float) -> dict:
    """How often the test miss rate exceeded servo's plus epsilon over the re-splits, its Clopper-Pearson 95 %
    interval, and the most exceedances a rate of delta allows (the 95 % quantile of Binomial(n, delta)).
    The re-splits share hits, so they are not independent: the interval is indicative."""
    exceeds = np.asarray(exceeds, bool)
    n, k = len(exceeds), int(exceeds.sum())
    low = 0.0 if k == 0 else float(beta.ppf(0.025, k, n - k + 1))
    high = 1.0 if k == n else float(beta.ppf(0.975, k + 1, n - k))
    allowed = int(binom.ppf(0.95, n, delta))
    return {"n_resplits": n, "exceedances": k, "exceed_rate_ci95_low_pct": 100 * low,
            "exceed_rate_ci95_high_pct": 100 * high, "allowed_exceedances": allowed, "bar_met": k <= allowed}


def risk_control_table(misses: np.ndarray, is_calibration: np.ndarray, lambdas, settings: RiskSettings,
                       rng: np.random.Generator) -> pd.DataFrame:
    """The dataset's own split, settings.n_resplits random re-splits of its calibration and test hits (as
    many calibrating), and the summary of how often the test miss rate exceeded servo's plus epsilon.

    misses (n, L) bool: the pooled hits' misses under each lambda; is_calibration (n,): the dataset's
    split."""
    is_calibration = np.asarray(is_calibration, bool)
    own = split_outcome(misses, np.flatnonzero(is_calibration), np.flatnonzero(~is_calibration), lambdas,
                        settings)
    resplits = resplit_outcomes(misses, int(is_calibration.sum()), lambdas, settings, rng)
    summary = exceedance_summary(resplits["exceeds"].to_numpy(), settings.delta)
    rows = pd.concat([pd.DataFrame([{"split": "dataset", **own}]), resplits], ignore_index=True)
    rows.insert(0, "kind", np.where(rows["split"] == "dataset", "dataset split", "re-split"))
    summary_row = {"kind": "summary", "split": f"{summary['n_resplits']} re-splits",
                   "exceeds": summary.pop("exceedances"), **summary,
                   "anticipatory_exceeds": int(resplits["anticipatory_exceeds"].sum()),
                   **{c: resplits[c].mean() for c in ("lambda", "servo_miss_pct", "anticipatory_miss_pct",
                                                       "risk_controlled_miss_pct", "excess_pct")},
                   "epsilon_pct": 100 * settings.epsilon}
    return pd.concat([rows, pd.DataFrame([summary_row])], ignore_index=True)


def family_misses(robot, hits: pd.DataFrame, flights: list, predictions: list, controllers: list[Controller],
                  settings: SimSettings) -> np.ndarray:
    """(n, L) bool: each hit's miss under servo (column 0, the lambda = 0 rule) and under each further
    controller of the family (evaluate.simulate_hits: the robot's own episodes)."""
    columns = [CONTROLLERS["servo"].fixed, *controllers[1:]]
    return np.column_stack([~simulate_hits(robot, hits, flights, predictions, c, settings)["hit_ball"]
                            .to_numpy(bool) for c in columns])


def stressed_predictions(predictions: list[Prediction], control: str,
                         rng: np.random.Generator | None = None) -> list[Prediction]:
    """The predictions of a stress control, each keeping its uncertainty: mirrored = strike x -> -x (a
    confidently wrong model that sends the robot the wrong way, the paper's failure made systematic);
    shuffled = every hit given another hit's predictions (drawn by rng: predictions that say nothing)."""
    if control == "mirrored":
        return [Prediction(p.frames, -p.strike_x, p.uncertainty) for p in predictions]
    if control == "shuffled":
        return [predictions[k] for k in rng.permutation(len(predictions))]
    raise ValueError(f"unknown stress control '{control}'; expected one of {STRESS_CONTROLS}")


def pooled_misses(robot, dataset: pd.DataFrame, balls: tuple, predictions: pd.DataFrame,
                  uncertainty: pd.DataFrame | None, risk: RiskSettings, settings: SimSettings,
                  max_flight_s: float, control: str | None = None, rng: np.random.Generator | None = None
                  ) -> tuple[pd.DataFrame, np.ndarray]:
    """(the calibration and test hits of a DATASET table, their misses (n, L) under each gain rule).

    balls: (judged, seen) ball tables by session (flights.hit_flights); predictions: the final model's;
    uncertainty: the configured estimator's table (None: only the uniform family). control: a stress
    control of the predictions (stressed_predictions; rng draws the shuffle)."""
    if uncertainty is None and risk.family != "uniform":
        raise ValueError(f"robot.risk_control.family '{risk.family}' reads an uncertainty: configure "
                         "robot.estimator, or use the uniform family")
    hits = dataset[dataset["split"].isin(["calibration", "test"])].reset_index(drop=True)
    flights = hit_flights(hits, balls[0], max_flight_s, balls[1])
    per_hit = hit_predictions(predictions, hits, uncertainty)
    if control is not None:
        per_hit = stressed_predictions(per_hit, control, rng)
    reference = (None if uncertainty is None else
                 np.concatenate([used_predictions(q, settings.episode).uncertainty for q in per_hit]))
    controllers = family_controllers(risk.family, risk.lambdas, reference)
    return hits, family_misses(robot, hits, flights, per_hit, controllers, settings)


def risk_control_report(robot, dataset: pd.DataFrame, balls: tuple, predictions: pd.DataFrame,
                        uncertainty: pd.DataFrame | None, risk: RiskSettings, settings: SimSettings,
                        max_flight_s: float, seed: int) -> tuple[pd.DataFrame, list[str]]:
    """(risk_control_table of the model's predictions and of each of risk.stress_controls, a column
    'predictions' saying which; the misses per lambda over all hits, as text)."""
    tables, sweeps = [], []
    for kind in ("model", *risk.stress_controls):
        control = None if kind == "model" else kind
        hits, misses = pooled_misses(robot, dataset, balls, predictions, uncertainty, risk, settings,
                                     max_flight_s, control, rng_for(seed, "robot_risk_control", kind))
        is_calibration = (hits["split"] == "calibration").to_numpy()
        table = risk_control_table(misses, is_calibration, risk.lambdas, risk,
                                   rng_for(seed, "robot_risk_control"))
        tables.append(table.assign(predictions=kind))
        sweeps.append(f"{kind} predictions " + ", ".join(
            f"{x:g}: {m}" for x, m in zip(risk.lambdas, misses.sum(axis=0), strict=True)))
    table = pd.concat(tables, ignore_index=True)
    table.insert(0, "predictions", table.pop("predictions"))
    return table, sweeps
