"""Train / calibration / test splits and cross-validation folds, grouped by rally.

Hits of one rally share players, strokes and ball flights, so a rally lies wholly in one part and one
fold; otherwise the test error would be measured on near-copies of training hits. Written here rather
than taken from scikit-learn (not a dependency; its GroupShuffleSplit balances the number of groups,
not of hits).
"""

import numpy as np
import pandas as pd

GROUP_COLUMNS = ["session", "rally"]


def _assign_balanced(sizes: np.ndarray, fractions: np.ndarray) -> np.ndarray:
    """Part (0..len(fractions)-1) of each group, visiting the groups in the given order and giving each to
    the part furthest below its share of the hits assigned so far (itself included): every part ends
    within about one group's size of its share."""
    counts = np.zeros(len(fractions))
    parts = np.empty(len(sizes), dtype=int)
    assigned = 0
    for g, size in enumerate(sizes):
        assigned += size
        parts[g] = int(np.argmax(fractions * assigned - counts))
        counts[parts[g]] += size
    return parts


def split_by_rally(hit_table: pd.DataFrame, rng: np.random.Generator, test_fraction: float = 0.2,
                   calibration_fraction: float = 0.1, n_folds: int = 5) -> pd.DataFrame:
    """hit_table (one row per hit, with 'session' and 'rally' columns) with two columns added:
    'split' in {'train', 'calibration', 'test'}, with about the given fractions of the hits, and 'fold'
    (0..n_folds-1 for train rows, of about equal hit counts; -1 otherwise). The rallies are visited in an
    order drawn from rng, so the result depends on the rng's seed only.
    """
    missing = [c for c in GROUP_COLUMNS if c not in hit_table.columns]
    if missing:
        raise ValueError(f"hit table lacks the columns {missing} that group hits into rallies")
    if not (0 <= test_fraction and 0 <= calibration_fraction and test_fraction + calibration_fraction < 1):
        raise ValueError(f"test ({test_fraction}) and calibration ({calibration_fraction}) fractions must be "
                         "non-negative and leave some training hits")
    if hit_table[GROUP_COLUMNS].isna().any().any():
        raise ValueError("hit table has hits without a session or rally id")
    if n_folds < 1:
        raise ValueError(f"n_folds must be at least 1, got {n_folds}")
    group_of_hit, sizes = _group_ids(hit_table)
    order = rng.permutation(len(sizes))
    fractions = np.array([1 - test_fraction - calibration_fraction, calibration_fraction, test_fraction])
    part = np.empty(len(sizes), dtype=int)
    part[order] = _assign_balanced(sizes[order], fractions)
    fold = np.full(len(sizes), -1)
    train = order[part[order] == 0]
    fold[train] = _assign_balanced(sizes[train], np.full(n_folds, 1 / n_folds))
    out = hit_table.copy()
    out["split"] = np.array(["train", "calibration", "test"])[part[group_of_hit]]
    out["fold"] = fold[group_of_hit]
    return out


def _group_ids(hit_table: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """Rally id of every hit (0..G-1, in sorted (session, rally) order, so row order does not matter) and
    the number of hits of each rally."""
    group_of_hit = hit_table.groupby(GROUP_COLUMNS, sort=True).ngroup().to_numpy()
    return group_of_hit, np.bincount(group_of_hit)
