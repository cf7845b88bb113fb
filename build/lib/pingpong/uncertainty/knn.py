"""The paper's k-NN regressor of the absolute strike-point error from the inputs.

The model is the standardised fitting rows (scikit-learn is not a dependency). Fitted on the training
hits' out-of-fold errors, so its targets are errors on unseen hits. The neighbours are found by exact
brute force (torch.cdist, torch.topk) in blocks of query rows, not by scipy's cKDTree: in the features'
79 dimensions a k-d tree prunes almost nothing, and on the default run (17k fitting rows, 24k query
rows) each application took ~50 s, 70 % of fit_uncertainty, which applies it four times;
benchmarks/bench_knn.py measures the two side by side, and a test checks the neighbours against cKDTree.
"""

from dataclasses import dataclass

import numpy as np
import torch

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


BLOCK_DISTANCES = 2**24  # distances held at once (float64: 128 MB), whatever the number of fitting rows


def nearest_rows(reference: np.ndarray, queries: np.ndarray, k: int) -> np.ndarray:
    """(Q, k) indices of each query row's k nearest reference rows (Euclidean), nearest first."""
    reference = torch.as_tensor(np.asarray(reference, float))
    queries = torch.as_tensor(np.asarray(queries, float))
    block = max(1, BLOCK_DISTANCES // max(len(reference), 1))
    return torch.cat([torch.topk(torch.cdist(rows, reference), k, largest=False).indices
                      for rows in queries.split(block)]).numpy()


def predict_knn(model: KnnErrorRegressor, features: np.ndarray) -> np.ndarray:
    """Mean absolute error (m) of the k nearest fitting rows (Euclidean, standardised features)."""
    idx = nearest_rows(model.features, (np.asarray(features, float) - model.mean) / model.std, model.k)
    return model.abs_errors[idx].mean(axis=1)


KNN_SCHEMA = Schema("knn_error_regressor", 1)


def save(model: KnnErrorRegressor, stem, prov: Provenance) -> None:
    """The fitting rows and standardisation as safetensors, k in the JSON sidecar (no pickle)."""
    tensors = {name: torch.from_numpy(np.ascontiguousarray(getattr(model, name)))
               for name in ("mean", "std", "features", "abs_errors")}
    save_model(tensors, {"k": model.k}, stem, KNN_SCHEMA, prov)


def load(stem) -> KnnErrorRegressor:
    tensors, hparams = load_model(stem, KNN_SCHEMA)
    return KnnErrorRegressor(**{k: v.numpy() for k, v in tensors.items()}, k=hparams["k"])
