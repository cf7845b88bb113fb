"""The controllers of the paper's Tables 2-4 (and one beyond it), registered by name.

A controller sets the speed share alpha of every control step before the first visual-servoing goal is
usable (evaluate.step_alphas); from then on every controller servos at alpha_servo = 1. A registered kind
is either one fixed controller or a grid of candidates that simulate_robot sweeps on the calibration
hits (sweep.py). The workflow, the robot's stages and the reports read the names from CONTROLLERS, so
adding a controller touches this module (docs/architecture.md, "Registries").

Light on purpose (numpy only): the Snakefile imports it.
"""

from collections.abc import Callable
from dataclasses import dataclass
from itertools import product

import numpy as np


@dataclass(frozen=True)
class Controller:
    name: str
    alpha1: float = 0.0  # speed share on the prediction before the hit
    alpha2: float = 0.0  # after the hit, until the first servo goal
    skip_centre: bool = False  # the paper's rule: no anticipation on a predicted strike in the centre
    confidence: tuple[float, float] | None = None  # (u_full, u_zero) m of the uncertainty ramp

    def to_choice(self) -> dict:
        """The settings as written to processed/sim/{controller}.json."""
        return {"controller": self.name, "alpha1": self.alpha1, "alpha2": self.alpha2,
                "skip_centre": self.skip_centre, "confidence_m": self.confidence}

    @classmethod
    def from_choice(cls, choice: dict) -> "Controller":
        """The controller simulate_robot chose, from its JSON settings."""
        confidence = choice.get("confidence_m")
        return cls(choice["controller"], float(choice["alpha1"]), float(choice["alpha2"]),
                   bool(choice["skip_centre"]), None if confidence is None else tuple(map(float, confidence)))


@dataclass(frozen=True)
class Tuning:
    """What a grid of candidates is built from: the config's alpha grid and confidence quantiles, and the
    calibration hits' uncertainties (None for a controller that reads none)."""

    alphas: list[float]
    quantiles: list[float]
    uncertainty: np.ndarray | None = None


@dataclass(frozen=True)
class ControllerKind:
    name: str
    fixed: Controller | None = None  # one controller, or
    grid: Callable[[str, Tuning], list[Controller]] | None = None  # candidates swept on calibration hits
    uses_uncertainty: bool = False  # follows the uncertainties of config robot.estimator, or
    uses_oracle: bool = False  # of the twin's strike oracle (twin runs only: the ceiling of confidence)
    description: str = ""

    @property
    def follows_uncertainty(self) -> bool:
        return self.uses_uncertainty or self.uses_oracle


def alpha_grid(name: str, tuning: Tuning) -> list[Controller]:
    """The paper's uncertainty-aware controller at every (alpha1, alpha2) of the grid."""
    alphas = tuning.alphas
    return [Controller(name, float(a1), float(a2), skip_centre=True) for a1, a2 in product(alphas, alphas)]


def confidence_grid(name: str, tuning: Tuning) -> list[Controller]:
    """The confidence ramp at every (u_full <= u_zero) pair of quantiles of the calibration uncertainties."""
    uncertainty = np.asarray(tuning.uncertainty, float)
    finite = uncertainty[np.isfinite(uncertainty)]
    if len(finite) == 0:  # e.g. a conformal factor from too few calibration hits is infinite
        raise ValueError("the confidence-scaled controller needs finite calibration uncertainties; the "
                         "configured estimator (config robot.estimator) gave none: choose another")
    levels = np.quantile(finite, sorted(tuning.quantiles))
    return [Controller(name, 1.0, 1.0, confidence=(float(lo), float(hi)))
            for i, lo in enumerate(levels) for hi in levels[i:]]


CONTROLLERS: dict[str, ControllerKind] = {}


def register(kind: ControllerKind) -> ControllerKind:
    if kind.name in CONTROLLERS:
        raise ValueError(f"a controller named '{kind.name}' is already registered")
    if (kind.fixed is None) == (kind.grid is None):
        raise ValueError(f"controller '{kind.name}': give either one fixed controller or a grid")
    CONTROLLERS[kind.name] = kind
    return kind


def controller_names(with_uncertainty: bool, with_oracle: bool = False) -> list[str]:
    """The registered controllers, in order; those that follow an estimator only `with_uncertainty`, the
    oracle only `with_oracle`."""
    return [name for name, kind in CONTROLLERS.items()
            if (with_uncertainty or not kind.uses_uncertainty) and (with_oracle or not kind.uses_oracle)]


register(ControllerKind("servo", fixed=Controller("servo"),
                        description="alpha1 = alpha2 = 0: the robot waits for visual servoing"))
register(ControllerKind("anticipatory", fixed=Controller("anticipatory", 1.0, 1.0),
                        description="alpha1 = alpha2 = 1 on the latest prediction from t = -10 frames"))
register(ControllerKind("uncertainty_aware", grid=alpha_grid,
                        description="the paper's: alpha1 before the hit, alpha2 after it, 0 while the latest "
                                    "predicted strike point lies in the centre region"))
register(ControllerKind("confidence_scaled", grid=confidence_grid, uses_uncertainty=True,
                        description="beyond the paper: alpha = ramp(u) of the latest prediction's calibrated "
                                    "uncertainty u, 1 for u <= u_full, 0 for u >= u_zero, linear between"))
register(ControllerKind("confidence_scaled_oracle", grid=confidence_grid, uses_oracle=True,
                        description="the confidence-scaled controller on the twin's strike oracle std (twin "
                                    "runs only): the most confidence scaling could win"))
