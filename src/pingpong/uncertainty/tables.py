"""The estimators' names (from the registry) and the layout of their output tables (light: the workflow
imports it)."""

from pingpong.common.artifacts import Schema
from pingpong.uncertainty import estimators as _registered  # noqa: F401  (fills the registry)
from pingpong.uncertainty.registry import REGISTRY

ESTIMATORS = tuple(REGISTRY)  # registration order: fitting, tables and reports
PAPER_ESTIMATORS = tuple(name for name, cls in REGISTRY.items() if cls.paper)
MODEL_FILES = tuple(cls.model_file for cls in REGISTRY.values() if cls.model_file)
HIT_KEYS = ["session", "rally", "hit"]
# one row per calibration or test hit and frame before the hit; uncertainty, lower, upper in m
# (lower/upper NaN where the estimator gives no interval)
UNCERTAINTY = Schema("uncertainty", 1, (*HIT_KEYS, "split", "frames_before_hit", "strike_x", "strike_x_pred",
                                        "abs_error", "uncertainty", "lower", "upper"))
FITTED = Schema("uncertainty_estimators", 1)  # estimators.json: fitted constants and diagnostics
