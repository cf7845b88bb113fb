"""Grid search bookkeeping: configurations with stable ids, cross-validation folds, selection."""

import itertools

import numpy as np
import pandas as pd

from pingpong.common.hashing import params_sha256


def config_id(config: dict) -> str:
    """Stable id of a configuration: 12 hex digits of the SHA-256 of its JSON (key order ignored).

    The same values give the same id on every run and machine, so Snakemake job names and saved
    results stay valid while the grid grows. Types count: 1 and 1.0 are different configurations.
    """
    return params_sha256(config)[:12]


def expand_grid(grid: dict) -> list[dict]:
    """Every combination of the grid's value lists, as dicts with an added 'config_id' key.

    Order: the product over the keys in the grid's own order (the last key varies fastest).
    """
    for key, values in grid.items():
        if not isinstance(values, list) or not values:
            raise ValueError(f"expand_grid: '{key}' must be a non-empty list of values, got {values!r}")
    configs = [dict(zip(grid, combo, strict=True)) for combo in itertools.product(*grid.values())]
    return [{"config_id": config_id(c), **c} for c in configs]


def grid_configurations(grid: dict, sample: int | None, extra: dict[str, dict],
                        rng: np.random.Generator) -> list[dict]:
    """The configurations a search trains: `sample` of the grid's (expand_grid) drawn at random without
    replacement, kept in grid order (all of them when sample is None or covers the grid), then each
    configuration of `extra` (name -> values) not already among them (e.g. the paper's own net, which
    lies outside its grid, and the default net), with its config_id. A random slice is the cheap search
    (Bergstra & Bengio 2012, JMLR 13): 100 draws hold one of the grid's best 5 % with probability
    1 - 0.95^100 = 0.994, where the paper's whole grid (2,916 x 5 folds) is a cluster's work."""
    configs = expand_grid(grid)
    if sample is not None and sample < len(configs):
        configs = [configs[i] for i in np.sort(rng.choice(len(configs), size=sample, replace=False))]
    ids = {c["config_id"] for c in configs}
    for name, values in extra.items():
        if set(values) != set(grid):
            raise ValueError(f"training.grid_extra.{name}: {values} must set exactly the grid's keys "
                             f"{sorted(grid)}")
        config = {"config_id": config_id(values), **values}
        if config["config_id"] not in ids:
            configs.append(config)
            ids.add(config["config_id"])
    return configs


def cv_folds(fold_ids) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """For each fold f of the training part: (train indices, validation indices) with validation = the
    hits whose fold id is f. Indices are positions in `fold_ids` (N,), ascending."""
    fold_ids = np.asarray(fold_ids)
    folds = np.unique(fold_ids)
    if len(folds) < 2:
        raise ValueError(f"cv_folds: need at least 2 distinct fold ids, got {folds.tolist()}")
    return {int(f): (np.flatnonzero(fold_ids != f), np.flatnonzero(fold_ids == f)) for f in folds}


def grid_summary(results: pd.DataFrame) -> pd.DataFrame:
    """Per configuration: mean_val_loss, std_val_loss (over folds, ddof=0), n_folds; best first.

    `results` has one row per (config_id, fold) with its val_loss. Every configuration must have
    every fold that appears in the results (a missing job would bias its mean).
    """
    missing_cols = {"config_id", "fold", "val_loss"} - set(results.columns)
    if missing_cols:
        raise ValueError(f"grid results lack columns {sorted(missing_cols)}")
    if results["val_loss"].isna().any():
        raise ValueError("grid results: val_loss has NaN; record a diverged job as inf")
    duplicated = results[results.duplicated(["config_id", "fold"], keep=False)]
    if len(duplicated):
        raise ValueError(f"grid results repeat (config_id, fold) pairs: "
                         f"{duplicated[['config_id', 'fold']].drop_duplicates().values.tolist()[:5]}")
    all_folds = set(results["fold"])
    for cid, folds in results.groupby("config_id")["fold"]:
        if set(folds) != all_folds:
            raise ValueError(f"grid results: config {cid} lacks folds {sorted(all_folds - set(folds))}")
    summary = results.groupby("config_id")["val_loss"].agg(
        mean_val_loss="mean", std_val_loss=lambda v: v.std(ddof=0), n_folds="count").reset_index()
    return summary.sort_values(["mean_val_loss", "config_id"], ignore_index=True)


def select_best(results: pd.DataFrame) -> str:
    """The config_id with the lowest mean validation loss over folds, across all cell types (ties:
    the smaller id)."""
    return str(grid_summary(results)["config_id"].iloc[0])
