"""Fitting every registered estimator on a run's hits, and what the fit_uncertainty rule writes of them."""

import numpy as np
import pandas as pd

from pingpong.curation.schemas import HIT_KEYS, dataset_arrays
from pingpong.learning.models import FRAMES_BEFORE_HIT
from pingpong.learning.train import predict, strike_points
from pingpong.uncertainty import estimators as _registered  # noqa: F401  (fills the registry)
from pingpong.uncertainty.estimators import PREDICTED
from pingpong.uncertainty.features import frame_features
from pingpong.uncertainty.metrics import spearman, within_frames
from pingpong.uncertainty.path_band import fit_path_band, fit_pointwise_band
from pingpong.uncertainty.registry import REGISTRY, Estimator, Hits, UncertaintySettings

TABLE_COLUMNS = [*HIT_KEYS, "split", "frames_before_hit", "strike_x", "strike_x_pred", "abs_error"]


def frame_rows(dataset: pd.DataFrame, predictions: pd.DataFrame) -> pd.DataFrame:
    """One row per (dataset hit, frame before the hit), in dataset order and FRAMES_BEFORE_HIT order
    within a hit (the row order of features.frame_features), with the final model's prediction
    (out of fold for training hits) and 'hit_index', the hit's row in `dataset`."""
    n, k = len(dataset), len(FRAMES_BEFORE_HIT)
    rows = dataset.iloc[np.repeat(np.arange(n), k)][[*HIT_KEYS, "split", "strike_x"]].reset_index(drop=True)
    rows["hit_index"] = np.repeat(np.arange(n), k)
    rows["frames_before_hit"] = np.tile(FRAMES_BEFORE_HIT, n)
    final = predictions.loc[predictions["model"] == "final", [*HIT_KEYS, "frames_before_hit", *PREDICTED]]
    rows = rows.merge(final, on=[*HIT_KEYS, "frames_before_hit"], how="left", validate="one_to_one")
    missing = rows["strike_x_pred"].isna()
    if missing.any():
        first = rows.loc[missing, HIT_KEYS].iloc[0].to_dict()
        raise ValueError(f"predictions: no 'final' prediction for {int(missing.sum())} (hit, frame) rows, "
                         f"first {first}; rebuild processed/predictions.parquet")
    rows["abs_error"] = np.abs(rows["strike_x_pred"] - rows["strike_x"])
    return rows


def estimator_hits(dataset: pd.DataFrame, predictions: pd.DataFrame, members: list) -> Hits:
    """The Hits of every dataset hit: its frame rows, their features, the inputs and every ensemble
    member's (AnticipationNet) strike points."""
    X, _ = dataset_arrays(dataset)
    ensemble_strike = np.stack([strike_points(predict(net, X)).reshape(-1) for net in members])
    return Hits(frame_rows(dataset, predictions), frame_features(X, FRAMES_BEFORE_HIT), X, ensemble_strike)


def fit_estimators(hits: Hits, settings: UncertaintySettings,
                   rng: np.random.Generator) -> dict[str, Estimator]:
    """Every registered estimator, fitted in registration order on the train and calibration rows."""
    split = set(hits.split)
    if not {"train", "calibration"} <= split:
        raise ValueError(f"fit_estimators: need training and calibration hits; splits {sorted(split)}")
    fitted: dict[str, Estimator] = {}
    for name in REGISTRY:
        estimator = REGISTRY[name](settings)
        estimator.fit(hits, fitted, rng)
        fitted[name] = estimator
    return fitted


def estimator_tables(hits: Hits, fitted: dict[str, Estimator]) -> dict[str, pd.DataFrame]:
    """Per estimator the UNCERTAINTY table of the calibration and test rows."""
    out = hits.split != "train"
    base = hits.rows.loc[out, TABLE_COLUMNS]
    nan = np.full(len(hits.rows), np.nan)
    tables = {}
    for name, estimator in fitted.items():
        band = estimator.apply(hits)
        lower, upper = (nan, nan) if band.lower is None else (band.lower, band.upper)
        std = band.predicted_std(estimator.settings.coverage)
        tables[name] = base.assign(uncertainty=band.uncertainty[out], lower=lower[out],
                                   upper=upper[out], std=std[out]).reset_index(drop=True)
    return tables


def _member_error_agreement(ensemble_strike, y, frames, rows_of) -> float:
    """Mean Spearman, within frames, between two members' absolute errors over the given rows, averaged
    over member pairs: near 1 when every member errs on the same hits (what no spread can see)."""
    errors = np.abs(ensemble_strike[:, rows_of] - y[rows_of])
    m = len(errors)
    return float(np.mean([within_frames(spearman, errors[i], errors[j], frames[rows_of])
                          for i in range(m) for j in range(i + 1, m)]))


def diagnostics(hits: Hits, fitted: dict[str, Estimator]) -> dict:
    """Why ranking may fail: how far the members err on the same test hits, and how well the error head
    ranks its own training errors (where it is fitted)."""
    out = {"member_error_spearman_within_frame":
           _member_error_agreement(hits.ensemble_strike, hits.y, hits.frames, hits.split == "test")}
    if "error_head" in fitted:
        train = hits.train
        head = fitted["error_head"].apply(hits).uncertainty
        out["error_head_training_spearman_within_frame"] = within_frames(
            spearman, head[train], hits.abs_error[train], hits.frames[train])
    return out


def _json_safe(value):
    """+inf (too few calibration hits for the nominal coverage) as null: JSON has no infinity."""
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def path_labels(dataset: pd.DataFrame, hits: Hits) -> tuple[np.ndarray, np.ndarray]:
    """(predicted, true) path parameters (a1, a2, b) of every row of hits (rows, 3)."""
    true = dataset[["a1", "a2", "b"]].to_numpy(float)[hits.column("hit_index")]
    return hits.rows[["a1", "a2", "b"]].to_numpy(float), true


def fit_path_bands(dataset: pd.DataFrame, hits: Hits, coverage: float) -> dict:
    """The whole-path bands (path_band.py), simultaneous and pointwise, as their JSON states: scales from
    the training hits' out-of-fold predictions, quantiles from the calibration hits."""
    pred, true = path_labels(dataset, hits)
    train, cal = hits.train, hits.calibration
    alpha = 1 - coverage
    simultaneous = fit_path_band(pred[train], true[train], hits.frames[train], pred[cal], true[cal],
                                 hits.frames[cal], hits.groups[cal], alpha)
    pointwise = fit_pointwise_band(pred[cal], true[cal], hits.frames[cal], hits.groups[cal], alpha)
    return {band.kind: band.state() for band in (simultaneous, pointwise)}


def fitted_record(hits: Hits, fitted: dict[str, Estimator], coverage: float, path_bands: dict) -> dict:
    """estimators.json: the coverage, every estimator's state under its name, the whole-path bands'
    states (fit_path_bands) and the diagnostics."""
    states = {name: e.state() for name, e in fitted.items() if e.state()}
    return _json_safe({"coverage": coverage, **states, "path_band": path_bands,
                       "diagnostics": diagnostics(hits, fitted)})


def _from_json(value):
    """null (written for +inf) back to +inf."""
    if isinstance(value, dict):
        return {k: _from_json(v) for k, v in value.items()}
    return float("inf") if value is None else value


def restore_estimators(record: dict, settings: UncertaintySettings,
                       model_stems: dict) -> dict[str, Estimator]:
    """The estimators of an estimators.json record (read_json) and their models (model_file -> stem), in
    registration order, ready to apply to new hits."""
    restored: dict[str, Estimator] = {}
    for name, cls in REGISTRY.items():
        estimator = cls(settings)
        estimator.restore(_from_json(record.get(name, {})), model_stems.get(cls.model_file), restored)
        restored[name] = estimator
    return restored
