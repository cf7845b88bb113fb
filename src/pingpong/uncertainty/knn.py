"""The paper's k-NN regressor of the absolute strike-point error from the inputs.

Written on scipy's cKDTree (the k-d tree is the whole model; scikit-learn is not a dependency).
Fitted on the training hits' out-of-fold errors, so its targets are errors on unseen hits.
"""

from dataclasses import dataclass

import numpy as np
import torch
from scipy.spatial import cKDTree

from pingpong.common.artifacts import Provenance, Schema, load_model, save_model
from pingpong.uncertainty.features import standardiser


@dataclass(frozen=True)
class KnnErrorRegressor:
    mean: np.ndarray  # feature standardisation, from the fitting rows
    std: np.ndarray
    features: np.ndarray  # (M, D) standardised fitting rows
    abs_errors: np.ndarray  # (M,) m
    k: int


def fit_knn(features: np.ndarray, abs_errors: np.ndarray, k: int) -> KnnErrorRegressor:
    """Store the standardised fitting rows and their errors; k is capped at the number of rows."""
    features, abs_errors = np.asarray(features, float), np.asarray(abs_errors, float)
    if len(features) != len(abs_errors) or not np.isfinite(abs_errors).all():
        raise ValueError(f"fit_knn: {len(features)} feature rows, {len(abs_errors)} errors "
                         f"({int((~np.isfinite(abs_errors)).sum())} non-finite)")
    mean, std = standardiser(features)
    return KnnErrorRegressor(mean, std, (features - mean) / std, abs_errors, min(k, len(features)))


def predict_knn(model: KnnErrorRegressor, features: np.ndarray) -> np.ndarray:
    """Mean absolute error (m) of the k nearest fitting rows (Euclidean, standardised features)."""
    _, idx = cKDTree(model.features).query((np.asarray(features, float) - model.mean) / model.std,
                                          k=model.k)
    return model.abs_errors[np.asarray(idx).reshape(len(features), -1)].mean(axis=1)


KNN_SCHEMA = Schema("knn_error_regressor", 1)


def save(model: KnnErrorRegressor, stem, prov: Provenance) -> None:
    """The fitting rows and standardisation as safetensors, k in the JSON sidecar (no pickle)."""
    tensors = {name: torch.from_numpy(np.ascontiguousarray(getattr(model, name)))
               for name in ("mean", "std", "features", "abs_errors")}
    save_model(tensors, {"k": model.k}, stem, KNN_SCHEMA, prov)


def load(stem) -> KnnErrorRegressor:
    tensors, hparams = load_model(stem, KNN_SCHEMA)
    return KnnErrorRegressor(**{k: v.numpy() for k, v in tensors.items()}, k=hparams["k"])
