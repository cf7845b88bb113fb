"""The simulated robot's report: the paper's Tables 2-4 per controller, and the joint limits (Table 6).

Tables 2-4 give, per region of the true strike point and over all test hits: total, hits, and the end
distance (paddle centre to ball at the strike line) as mean +- 0.5 std. Beside them, each controller is
compared with visual servoing alone on the same hits, and each confidence-scaled controller with the
paper's uncertainty-aware one: the exact (binomial) McNemar test on the discordant pairs and a paired
bootstrap interval of the difference in hits.
"""

import numpy as np
import pandas as pd
from scipy.stats import binomtest

from pingpong.curation.schemas import HIT_KEYS
from pingpong.robot.controllers import CONTROLLERS
from pingpong.robot.evaluate import bootstrap_hit_difference
from pingpong.robot.model import N_BASE, Robot

REGIONS = ("left", "centre", "right", "all")
BASELINE = "servo"
PAPER_CONTROLLER = "uncertainty_aware"  # what a controller that follows an uncertainty must beat
# the paper's Tables 2-4 (223 test hits): per region (total, hits, end distance mean cm, 0.5 std cm)
PAPER_TABLES = {
    "servo": {"right": (101, 60, 10.13, 4.38), "centre": (81, 60, 6.26, 1.93), "left": (41, 24, 12.82, 7.31),
              "all": (223, 144, 9.22, 4.615)},
    "anticipatory": {"right": (101, 67, 8.33, 3.85), "centre": (81, 59, 5.9, 1.87),
                     "left": (41, 20, 13.63, 7.41), "all": (223, 146, 8.42, 4.46)},
    "uncertainty_aware": {"right": (101, 70, 8.35, 3.72), "centre": (81, 59, 5.84, 1.78),
                          "left": (41, 22, 12.5, 7.18), "all": (223, 151, 8.2, 4.27)},
}


def region_rows(sim: pd.DataFrame) -> pd.DataFrame:
    """Per region and 'all': total, hits, hit %, end distance mean and 0.5 std (cm), limit breaches."""
    rows = []
    for region in REGIONS:
        part = sim if region == "all" else sim[sim["region"] == region]
        distance_cm = 100 * part["end_distance_m"]
        rows.append({"region": region, "total": len(part), "hits": int(part["hit_ball"].sum()),
                     "hit_pct": 100 * part["hit_ball"].mean() if len(part) else np.nan,
                     "end_distance_mean_cm": distance_cm.mean(),
                     "end_distance_half_std_cm": 0.5 * distance_cm.std(ddof=0),
                     "limit_breaches": int((~part["limits_ok"]).sum())})
    return pd.DataFrame(rows)


def mcnemar_exact(hits_a: np.ndarray, hits_b: np.ndarray) -> float:
    """Two-sided exact McNemar p-value of paired hit/miss outcomes (binomial test on the discordant pairs)."""
    a_only = int(np.sum(hits_a & ~hits_b))
    b_only = int(np.sum(~hits_a & hits_b))
    return 1.0 if a_only + b_only == 0 else float(binomtest(b_only, a_only + b_only, 0.5).pvalue)


def _paired_comparison(base: pd.Series, sim: pd.DataFrame, name: str, base_name: str,
                       rng: np.random.Generator, n_boot: int) -> tuple[int, float, float, float]:
    """(hits of `sim` minus hits of `base` on the same hits, bootstrap 95 % interval, exact McNemar p)."""
    paired = sim.set_index(HIT_KEYS)["hit_ball"].reindex(base.index)
    if paired.isna().any():
        raise ValueError(f"controller '{name}' was not simulated on the same hits as '{base_name}'")
    ours, theirs = paired.to_numpy(bool), base.to_numpy(bool)
    low, high = bootstrap_hit_difference(theirs, ours, rng, n_boot)
    return int(ours.sum() - theirs.sum()), low, high, mcnemar_exact(theirs, ours)


SERVO_COLUMNS = ("hits_minus_servo", "diff_ci95_low", "diff_ci95_high", "mcnemar_p")
PAPER_COLUMNS = (f"hits_minus_{PAPER_CONTROLLER}", "paper_ua_diff_ci95_low", "paper_ua_diff_ci95_high",
                 "paper_ua_mcnemar_p")


def robot_table(sims: dict[str, pd.DataFrame], rng: np.random.Generator, n_boot: int = 2000) -> pd.DataFrame:
    """Tables 2-4 for every controller (SIM tables by name), with the comparison against 'servo' on the
    'all' rows: difference in hits, its bootstrap 95 % interval and the exact McNemar p-value; and, for the
    controllers that follow an uncertainty (an estimator's or the oracle's), the same against the paper's
    uncertainty-aware controller (PAPER_COLUMNS), where it ran."""
    servo = sims[BASELINE].set_index(HIT_KEYS)["hit_ball"]
    paper = sims[PAPER_CONTROLLER].set_index(HIT_KEYS)["hit_ball"] if PAPER_CONTROLLER in sims else None
    parts = []
    for name, sim in sims.items():
        table = region_rows(sim)
        table.insert(0, "controller", name)
        compared = {SERVO_COLUMNS: _paired_comparison(servo, sim, name, BASELINE, rng, n_boot),
                    PAPER_COLUMNS: (np.nan,) * 4}
        if paper is not None and name in CONTROLLERS and CONTROLLERS[name].follows_uncertainty:
            compared[PAPER_COLUMNS] = _paired_comparison(paper, sim, name, PAPER_CONTROLLER, rng, n_boot)
        for columns, values in compared.items():
            for column, value in zip(columns, values, strict=True):
                table[column] = np.where(table["region"] == "all", value, np.nan)
        parts.append(with_paper(table, name))
    return pd.concat(parts, ignore_index=True)


def with_paper(table: pd.DataFrame, controller: str) -> pd.DataFrame:
    """The paper's total, hits and hit % for the same controller and region beside ours (NaN: not in it)."""
    paper = PAPER_TABLES.get(controller, {})
    rows = [paper.get(region, (np.nan,) * 4) for region in table["region"]]
    total, hits = (np.array([r[k] for r in rows], float) for k in (0, 1))
    return table.assign(paper_total=total, paper_hits=hits, paper_hit_pct=100 * hits / total)


def limits_table(robot: Robot, derived: dict[str, np.ndarray],
                 acceleration_sets: dict[str, np.ndarray]) -> pd.DataFrame:
    """One row per joint: the limits the controller uses, every acceleration set of limits.yaml
    (acceleration_{set}) and the accelerations derived from the torque limits (model.worst_case_accelerations;
    NaN for the base, whose drive forces are not modelled)."""
    n = len(robot.joint_names)
    arm = lambda values: np.concatenate([np.full(N_BASE, np.nan), values])  # noqa: E731
    table = pd.DataFrame({
        "joint": robot.joint_names,
        "unit": ["m"] * N_BASE + ["rad"] * (n - N_BASE),
        "position_min": robot.q_min, "position_max": robot.q_max,
        "velocity_max": robot.v_max, "acceleration_used": robot.a_max,
        **{f"acceleration_{name}": values for name, values in acceleration_sets.items()},
        "torque_max_Nm": arm(robot.tau_max),
        "derived_simple_min": arm(derived["simple_min"]),
        "derived_coupled_min": arm(derived["coupled_min"]),
        "derived_coupled_median": arm(derived["coupled_median"]),
    })
    table["headroom"] = table["derived_coupled_min"] / table["acceleration_used"]
    return table
