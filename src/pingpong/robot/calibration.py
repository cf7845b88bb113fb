"""A regime calibrated to the paper's Table 2: the sensing, servo and reach knobs (not the data) that make
visual servoing alone reproduce the paper's per-region hit rates and end distances on the fitting hits.

Why these knobs (measured on the default run of fb04da0, 411 training and calibration hits, servo alone
under the paper's robot and timing): with a perfect ball our servo hits centre 87 %, left 68 %, right 58 %
(the paper: 74, 59, 59), and its side misses are reach misses: given the true strike point at the first
servo goal (t = +10) the robot still misses 30 % of left and 37 % of right balls, 8-63 cm away, mostly
fast balls (strike 0.38 s after the hit on average, against 0.68 s for the ones it reaches;
analysis/table2_misses.py). Sensing noise costs every region alike (5 mm: centre 77, left 56, right 45),
so no sensing knob brings the centre down to 74 % and keeps the sides at 59 %: the paper's servo loses
centre balls to its estimate and keeps more side balls than our robot can reach.
The knobs therefore act on two things:
  - the servo's estimate: the seen ball's noise (regimes.Sensing; dropout and delay as well, if the config
    lists values) and the servo fit (the paper's two quadratics by default: it is the paper's method);
  - the reach: the base's top speed (the side balls' ceiling; the centre's need no base) and where the
    base waits across the table. The robot is symmetric (the flights mirrored in x swap the left and
    right rates exactly: 68.3 and 58.5 %), the twin's balls to the right are the harder ones to reach; the
    paper's left and right rates are equal, and it does not say where its robot waits.
The paddle stays the paper's (8 cm radius): a stated number, not a knob.

The knobs are searched over the grid of config robot.calibration; every grid point is simulated on the
fitting hits (servo only), and the point with the least misfit wins (ties: the first in grid order):
    sum over regions of ((hit rate - paper's) / HIT_RATE_SCALE)^2
                      + ((mean end distance - paper's) / paper's half std)^2
with the paper's half standard deviation (Table 2 reports mean +- 0.5 std) as each region's scale.
"""

from collections.abc import Callable
from itertools import product

import numpy as np
import pandas as pd
from scipy.stats import binom, binomtest

# Rahmanian et al. 2023, Table 2 (alpha1 = alpha2 = 0, visual servoing alone, 223 test hits of their lab):
# region -> (balls hit, total, end distance mean cm, 0.5 std cm)
PAPER_TABLE2 = {"left": (24, 41, 12.82, 7.31), "centre": (60, 81, 6.26, 1.93),
                "right": (60, 101, 10.13, 4.38)}
HIT_RATE_SCALE = 0.08  # a hit-rate miss of 8 points weighs as much as one half std of end distance
SENSING_KNOBS = ("noise_m", "delay_frames", "dropout")  # regimes.Sensing
DYNAMICS_KNOBS = ("base_speed_mps", "base_start_x_m")  # regimes.Dynamics
KNOBS = (*SENSING_KNOBS, "servo_fit", *DYNAMICS_KNOBS)
BAR_POINTS = 8.0  # the bar: each region's hit rate within 8 percentage points of the paper's


def region_stats(sim: pd.DataFrame) -> pd.DataFrame:
    """Per region of a SIM table: n, hits, hit_rate and the end distance's mean (cm)."""
    rows = []
    for region in PAPER_TABLE2:
        part = sim[sim["region"] == region]
        rows.append({"region": region, "n": len(part), "hits": int(part["hit_ball"].sum()),
                     "hit_rate": float(part["hit_ball"].mean()) if len(part) else np.nan,
                     "end_distance_cm": 100 * float(part["end_distance_m"].mean()) if len(part) else np.nan})
    return pd.DataFrame(rows)


def misfit(stats: pd.DataFrame, target: dict = PAPER_TABLE2) -> float:
    """The calibration's objective (module docstring); regions without hits are left out."""
    total = 0.0
    for row in stats.itertuples():
        hits, n, mean_cm, half_std_cm = target[row.region]
        if row.n == 0:
            continue
        total += ((row.hit_rate - hits / n) / HIT_RATE_SCALE) ** 2
        total += ((row.end_distance_cm - mean_cm) / half_std_cm) ** 2
    return float(total)


def knob_grid(grid: dict) -> list[dict]:
    """Every combination of the candidate values of the knobs the grid names (config robot.calibration),
    in KNOBS order (the first outermost)."""
    knobs = [k for k in KNOBS if k in grid]
    return [dict(zip(knobs, values, strict=True)) for values in product(*(grid[k] for k in knobs))]


def calibrate(simulate: Callable[[dict], pd.DataFrame], grid: dict,
              target: dict = PAPER_TABLE2) -> tuple[dict, pd.DataFrame]:
    """(the best knobs, one row per grid point: the knobs, misfit and per-region hit rates and distances).

    simulate(knobs) -> a SIM table (region, hit_ball, end_distance_m) of the calibration hits under them."""
    rows = []
    for knobs in knob_grid(grid):
        stats = region_stats(simulate(knobs)).set_index("region")
        rows.append({**knobs, "misfit": misfit(stats.reset_index(), target),
                     **{f"hit_rate_{r}": stats.loc[r, "hit_rate"] for r in target},
                     **{f"end_distance_cm_{r}": stats.loc[r, "end_distance_cm"] for r in target}})
    table = pd.DataFrame(rows)
    best = table.iloc[int(np.argmin(table["misfit"].to_numpy()))]
    return {k: (best[k].item() if hasattr(best[k], "item") else best[k]) for k in KNOBS if k in grid}, table


def bar_probability(n: int, rate: float, points: float = BAR_POINTS) -> float:
    """The probability that a perfectly calibrated servo (true hit rate `rate`) shows a rate within `points`
    percentage points of it on n hits (binomial): what the bar can show on that many hits."""
    if n == 0:
        return np.nan
    low, high = np.ceil(n * (rate - points / 100) - 1e-9), np.floor(n * (rate + points / 100) + 1e-9)
    return float(binom.cdf(high, n, rate) - binom.cdf(low - 1, n, rate))


def hit_rate_interval(hits: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Clopper-Pearson (exact) interval of a hit rate (scipy.stats.binomtest); nan for no hits."""
    if n == 0:
        return np.nan, np.nan
    ci = binomtest(int(hits), int(n)).proportion_ci(level, method="exact")
    return float(ci.low), float(ci.high)


def paper_bar(stats: pd.DataFrame, target: dict = PAPER_TABLE2, points: float = BAR_POINTS) -> pd.DataFrame:
    """Per region: the paper's hit rate and end distance range beside ours, whether ours is within
    `points` percentage points and within mean +- 0.5 std (the issue's bar for the calibrated regime),
    our rate's 95 % Clopper-Pearson interval and whether the paper's rate lies in it, and the probability
    that a servo calibrated perfectly to the paper's rate meets the points bar on this many hits."""
    rows = []
    for row in stats.itertuples():
        hits, n, mean_cm, half_std_cm = target[row.region]
        low, high = hit_rate_interval(row.hits, row.n)
        rows.append({"region": row.region, "n": row.n, "hits": row.hits, "hit_pct": 100 * row.hit_rate,
                     "hit_pct_ci95_low": 100 * low, "hit_pct_ci95_high": 100 * high,
                     "paper_hit_pct": 100 * hits / n,
                     "paper_in_ci95": bool(low <= hits / n <= high),
                     "bar_probability_if_calibrated": bar_probability(row.n, hits / n, points),
                     "end_distance_mean_cm": row.end_distance_cm,
                     "paper_end_distance_cm": mean_cm, "paper_range_low_cm": mean_cm - half_std_cm,
                     "paper_range_high_cm": mean_cm + half_std_cm,
                     "hit_rate_within": bool(abs(100 * row.hit_rate - 100 * hits / n) <= points),
                     "end_distance_within": bool(abs(row.end_distance_cm - mean_cm) <= half_std_cm)})
    return pd.DataFrame(rows)
