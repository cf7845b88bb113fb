"""Every uncertainty estimator fitted and applied to the final model's strike-point predictions.

Parts (DATASET's split, by rally): the k-NN regressor, the quantile heads and the error head learn
from the training hits' out-of-fold errors; every conformal quantile and the time-to-hit trend come from the
calibration hits (grouped by hit, see conformal.py); the estimators are applied to the calibration
and test hits. Every estimator scores the same point predictions (the final model's), so their
errors are shared and only the uncertainty differs.
"""

import numpy as np
import pandas as pd

from pingpong.learning.models import FRAMES_BEFORE_HIT
from pingpong.uncertainty.conformal import (
    conformal_quantile,
    cqr_scores,
    mondrian_quantiles,
    normalised_scores,
)
from pingpong.uncertainty.error_head import fit_error_head, predict_error
from pingpong.uncertainty.knn import fit_knn, predict_knn
from pingpong.uncertainty.metrics import spearman, within_frames
from pingpong.uncertainty.quantile_heads import fit_quantile_heads, predict_quantiles
from pingpong.uncertainty.tables import ESTIMATORS, HIT_KEYS
from pingpong.uncertainty.time_to_hit import fit_trend, trend

DIFFICULTY_FLOOR = 0.1  # sigma = difficulty + this share of its calibration median: no zero widths
_PREDICTED = ["a1", "a2", "b", "strike_x_pred"]


def frame_rows(dataset: pd.DataFrame, predictions: pd.DataFrame) -> pd.DataFrame:
    """One row per (dataset hit, frame before the hit), in dataset order and FRAMES_BEFORE_HIT order
    within a hit (the row order of features.frame_features), with the final model's prediction
    (out of fold for training hits) and 'hit_index', the hit's row in `dataset`."""
    n, k = len(dataset), len(FRAMES_BEFORE_HIT)
    rows = dataset.iloc[np.repeat(np.arange(n), k)][[*HIT_KEYS, "split", "strike_x"]].reset_index(drop=True)
    rows["hit_index"] = np.repeat(np.arange(n), k)
    rows["frames_before_hit"] = np.tile(FRAMES_BEFORE_HIT, n)
    final = predictions.loc[predictions["model"] == "final", [*HIT_KEYS, "frames_before_hit", *_PREDICTED]]
    rows = rows.merge(final, on=[*HIT_KEYS, "frames_before_hit"], how="left", validate="one_to_one")
    missing = rows["strike_x_pred"].isna()
    if missing.any():
        first = rows.loc[missing, HIT_KEYS].iloc[0].to_dict()
        raise ValueError(f"predictions: no 'final' prediction for {int(missing.sum())} (hit, frame) rows, "
                         f"first {first}; rebuild processed/predictions.parquet")
    rows["abs_error"] = np.abs(rows["strike_x_pred"] - rows["strike_x"])
    return rows


def _normalised(abs_error, difficulty, cal, groups, alpha) -> tuple[np.ndarray, dict]:
    floor = DIFFICULTY_FLOOR * float(np.median(difficulty[cal]))
    sigma = difficulty + floor
    q = conformal_quantile(normalised_scores(abs_error[cal], sigma[cal]), alpha, groups[cal])
    return q * sigma, {"quantile": q, "floor": floor}


def _member_error_agreement(ensemble_strike, y, frames, rows_of) -> float:
    """Mean Spearman, within frames, between two members' absolute errors over the given rows, averaged
    over member pairs: near 1 when every member errs on the same hits (what no spread can see)."""
    errors = np.abs(ensemble_strike[:, rows_of] - y[rows_of])
    m = len(errors)
    return float(np.mean([within_frames(spearman, errors[i], errors[j], frames[rows_of])
                          for i in range(m) for j in range(i + 1, m)]))


def fit_estimators(rows: pd.DataFrame, features: np.ndarray, X: np.ndarray, ensemble_strike: np.ndarray,
                   coverage: float, knn_k: int, heads_settings: dict, error_head_settings: dict,
                   rng: np.random.Generator):
    """(tables, fitted, models): per estimator the UNCERTAINTY table of the calibration and test rows;
    the fitted constants and diagnostics (JSON-able); the learned models ('knn', 'quantile_heads',
    'error_head').

    rows: `frame_rows`; features: `features.frame_features` of the same rows; X (hits, T, 39): the
    dataset's inputs (rows are hit-major, FRAMES_BEFORE_HIT order within a hit); ensemble_strike
    (M, rows): every member's strike-point x. Half-widths serve as the uncertainty of interval methods.
    """
    alpha = 1 - coverage
    split, groups = rows["split"].to_numpy(), rows["hit_index"].to_numpy()
    train, cal, out = split == "train", split == "calibration", split != "train"
    pred, err = rows["strike_x_pred"].to_numpy(), rows["abs_error"].to_numpy()
    frames, y = rows["frames_before_hit"].to_numpy(), rows["strike_x"].to_numpy()
    if not cal.any() or not train.any():
        raise ValueError(f"fit_estimators: need training and calibration hits; splits {sorted(set(split))}")

    half, fitted = {}, {"coverage": coverage}
    spread = ensemble_strike.std(axis=0, ddof=1)
    knn = fit_knn(features[train], err[train], knn_k)
    knn_error = np.zeros(len(rows))
    knn_error[~train] = predict_knn(knn, features[~train])
    fitted["knn"] = {"k": knn.k}
    intercept, slope = fit_trend(frames[cal], err[cal])
    fitted["time_to_hit"] = {"intercept": intercept, "slope": slope}
    fitted["conformal"] = {"quantile": conformal_quantile(err[cal], alpha, groups[cal])}
    half["conformal"] = np.full(len(rows), fitted["conformal"]["quantile"])
    by_frame = mondrian_quantiles(err[cal], frames[cal], alpha, groups[cal])
    fitted["mondrian"] = {"quantile_by_frame": {str(f): q for f, q in by_frame.items()}}
    half["mondrian"] = np.array([by_frame[f] for f in frames])
    half["normalised_knn"], fitted["normalised_knn"] = _normalised(err, knn_error, cal, groups, alpha)
    half["normalised_ensemble"], fitted["normalised_ensemble"] = _normalised(err, spread, cal, groups, alpha)
    k = len(FRAMES_BEFORE_HIT)
    train_hits, pred_by_hit = train.reshape(-1, k)[:, 0], pred.reshape(-1, k)
    error_head = fit_error_head(X[train_hits], pred_by_hit[train_hits], err.reshape(-1, k)[train_hits], rng,
                                **error_head_settings)
    head_error = predict_error(error_head, X, pred_by_hit).reshape(-1)
    half["normalised_error_head"], fitted["normalised_error_head"] = _normalised(err, head_error, cal, groups,
                                                                                 alpha)
    test = split == "test"
    fitted["diagnostics"] = {
        "member_error_spearman_within_frame": _member_error_agreement(ensemble_strike, y, frames, test),
        "error_head_training_spearman_within_frame": within_frames(spearman, head_error[train], err[train],
                                                                   frames[train]),
    }

    head_inputs = np.hstack([features, rows[_PREDICTED].to_numpy(float)])
    heads = fit_quantile_heads(head_inputs[train], (y - pred)[train], (alpha / 2, 1 - alpha / 2), rng,
                               **heads_settings)
    quantiles = pred[:, None] + predict_quantiles(heads, head_inputs)
    q = conformal_quantile(cqr_scores(y[cal], quantiles[cal, 0], quantiles[cal, 1]), alpha, groups[cal])
    fitted["cqr"] = {"quantile": q, "levels": list(heads.levels)}
    cqr_lower, cqr_upper = quantiles[:, 0] - q, quantiles[:, 1] + q

    uncertainty = {"ensemble": spread, "knn": knn_error, "time_to_hit": trend(intercept, slope, frames),
                   "error_head": head_error, **half, "cqr": (cqr_upper - cqr_lower) / 2}
    bounds = {name: (pred - h, pred + h) for name, h in half.items()} | {"cqr": (cqr_lower, cqr_upper)}
    base = rows.loc[out, [*HIT_KEYS, "split", "frames_before_hit", "strike_x", "strike_x_pred", "abs_error"]]
    tables = {}
    for name in ESTIMATORS:
        lower, upper = bounds.get(name, (np.full(len(rows), np.nan),) * 2)
        tables[name] = base.assign(uncertainty=uncertainty[name][out], lower=lower[out],
                                   upper=upper[out]).reset_index(drop=True)
    return tables, fitted, {"knn": knn, "quantile_heads": heads, "error_head": error_head}
