"""The uncertainty stages' table layouts (light: readers such as the robot do not hash the estimators)."""

from pingpong.common.artifacts import Schema
from pingpong.curation.schemas import HIT_KEYS

# one row per calibration or test hit and frame before the hit; uncertainty, lower, upper, std in m
# (lower/upper NaN where the estimator gives no interval; std: registry.Band.predicted_std)
UNCERTAINTY = Schema("uncertainty", 2, (*HIT_KEYS, "split", "frames_before_hit", "strike_x", "strike_x_pred",
                                        "abs_error", "uncertainty", "lower", "upper", "std"))
FITTED = Schema("uncertainty_estimators", 1)  # estimators.json: fitted constants and diagnostics
