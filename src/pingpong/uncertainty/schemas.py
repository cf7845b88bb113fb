"""The uncertainty stages' table layouts (light: readers such as the robot do not hash the estimators)."""

from pingpong.common.artifacts import Schema

HIT_KEYS = ["session", "rally", "hit"]
# one row per calibration or test hit and frame before the hit; uncertainty, lower, upper in m
# (lower/upper NaN where the estimator gives no interval)
UNCERTAINTY = Schema("uncertainty", 1, (*HIT_KEYS, "split", "frames_before_hit", "strike_x", "strike_x_pred",
                                        "abs_error", "uncertainty", "lower", "upper"))
FITTED = Schema("uncertainty_estimators", 1)  # estimators.json: fitted constants and diagnostics
