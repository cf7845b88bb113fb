"""The registered estimators' names, in registration order (light: the workflow imports it)."""

from pingpong.uncertainty import estimators as _registered  # noqa: F401  (fills the registry)
from pingpong.uncertainty.registry import REGISTRY

ESTIMATORS = tuple(REGISTRY)  # registration order: fitting, tables and reports
PAPER_ESTIMATORS = tuple(name for name, cls in REGISTRY.items() if cls.paper)
MODEL_FILES = tuple(cls.model_file for cls in REGISTRY.values() if cls.model_file)
