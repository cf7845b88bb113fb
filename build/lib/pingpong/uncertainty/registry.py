"""The estimator interface and its registry: every uncertainty estimator is a class registered by name.

An estimator is fitted on the training hits (models that learn errors) and the calibration hits
(conformal quantiles, trends), applied to any hits, and saved: its constants as JSON (`state`, in
processed/uncertainty/estimators.json under its name) and, where it learns a model, that model as
safetensors (`model_file`). Registration order is fitting order (an estimator may build on those
before it, e.g. normalised conformal on the k-NN error) and the order of every table and report.
The workflow, the config's enums, the reports and the robot read the names from here (through
`pingpong.uncertainty.names`), so adding an estimator touches one module: `pingpong.uncertainty.estimators`
(docs/architecture.md, "Registries").

Light on purpose (numpy, pandas and the config's helpers only): the Snakefile imports it.
"""

from dataclasses import dataclass
from statistics import NormalDist
from typing import ClassVar

import numpy as np
import pandas as pd

from pingpong.common.config import Settings


@dataclass(frozen=True)
class UncertaintySettings(Settings):
    """The config's `uncertainty` section, typed (defaults: config/schema.yaml only)."""

    coverage: float
    knn_k: int
    quantile_hidden: int
    quantile_epochs: int
    error_head_hidden: int
    error_head_epochs: int
    hetero_hidden: int
    hetero_epochs: int


@dataclass(frozen=True, eq=False)
class Hits:
    """What every estimator sees: one row per (hit, frame before the hit) of `rows` (fit.frame_rows:
    hit-major, FRAMES_BEFORE_HIT order within a hit), the rows' features, the hits' inputs X
    (hits, T, 39) and every ensemble member's strike-point x (members, rows)."""

    rows: pd.DataFrame
    features: np.ndarray
    X: np.ndarray
    ensemble_strike: np.ndarray

    def column(self, name: str) -> np.ndarray:
        return self.rows[name].to_numpy()

    split = property(lambda self: self.column("split"))
    groups = property(lambda self: self.column("hit_index"), doc="each row's hit: conformal groups by it")
    ensemble_spread = property(lambda self: self.ensemble_strike.std(axis=0, ddof=1),
                               doc="the std of the members' strike points per row (m)")
    frames = property(lambda self: self.column("frames_before_hit"))
    pred = property(lambda self: self.column("strike_x_pred"))
    y = property(lambda self: self.column("strike_x"))
    abs_error = property(lambda self: self.column("abs_error"))
    train = property(lambda self: self.split == "train")
    calibration = property(lambda self: self.split == "calibration")

    def by_hit(self, values: np.ndarray) -> np.ndarray:
        """Row values as (hits, frames)."""
        return np.asarray(values).reshape(len(self.X), -1)


@dataclass(frozen=True)
class Band:
    """An estimator's output on every row of the Hits it was applied to: the uncertainty (m; the
    half-width for interval methods), the interval's bounds (m), None where it gives no interval, and
    the std of the strike x it implies (m; None: derived by `Band.predicted_std`)."""

    uncertainty: np.ndarray
    lower: np.ndarray | None = None
    upper: np.ndarray | None = None
    std: np.ndarray | None = None

    def predicted_std(self, coverage: float) -> np.ndarray:
        """The std a Gaussian error would have: given, or a central `coverage` interval's half-width over
        its normal quantile, or else (an expected |error|) the uncertainty times sqrt(pi / 2)."""
        if self.std is not None:
            return self.std
        if self.lower is not None:
            return (self.upper - self.lower) / 2 / NormalDist().inv_cdf(0.5 + coverage / 2)
        return self.uncertainty * np.sqrt(np.pi / 2)


class Estimator:
    """The interface. `fit` sees the Hits (train and calibration rows), the estimators fitted before it
    and the run's generator; `apply` gives a Band on any Hits; `state` and `save_model` keep what
    `restore` needs to apply it again."""

    name: ClassVar[str]
    paper: ClassVar[bool] = False  # one of the paper's four
    model_file: ClassVar[str | None] = None  # stem of its model under processed/uncertainty/, if any

    def __init__(self, settings: UncertaintySettings):
        self.settings = settings

    @property
    def alpha(self) -> float:
        return 1 - self.settings.coverage

    @property
    def z(self) -> float:
        """The normal quantile of a central interval at the nominal coverage."""
        return NormalDist().inv_cdf(1 - self.alpha / 2)

    def fit(self, hits: Hits, fitted: dict, rng: np.random.Generator) -> None:
        """Learn from hits.train / calibrate on hits.calibration; `fitted`: estimators fitted so far."""

    def apply(self, hits: Hits) -> Band:
        raise NotImplementedError

    def state(self) -> dict:
        """The fitted constants, JSON-able (empty: nothing to write)."""
        return {}

    def save_model(self, stem, prov) -> None:
        raise NotImplementedError(f"estimator '{self.name}' has no model to save")

    def restore(self, state: dict, model_stem, fitted: dict) -> None:
        """Set the fitted state from `state` and the model at `model_stem` (as `fit` would have)."""


REGISTRY: dict[str, type[Estimator]] = {}


def register(cls: type[Estimator]) -> type[Estimator]:
    """Class decorator: add an estimator under its name (a second one of the same name is an error)."""
    if cls.name in REGISTRY:
        raise ValueError(f"an uncertainty estimator named '{cls.name}' is already registered")
    REGISTRY[cls.name] = cls
    return cls
