"""Robot regimes: named sets of dynamics, timing, sensing and servo model (config robot.regimes).

A regime says what the simulated robot is and how it sees the ball:
  - dynamics: the arm's acceleration set of config/robot/limits.yaml (its joint speeds are KUKA's), and
    the base's acceleration and speed (its two prismatic joints);
  - timing: control step, latency and the goal schedule (episode.EpisodeParams);
  - sensing: the 3D ball the visual servo sees, degraded from the measured one: Gaussian noise per
    coordinate, frames dropped at random, and a delay (the servo at frame f sees frames up to f - delay);
  - servo_fit: the servo's strike estimate (servo.SERVO_FITS).
A regime with `calibrated: true` takes its sensing, servo fit and the calibrated dynamics knobs (base speed
and start) from a calibration artifact (calibration.py, rule calibrate_regime) instead of the config.
Light on purpose (no Pinocchio).
"""

import zlib
from dataclasses import dataclass, fields, replace
from itertools import product

import numpy as np

from pingpong.common.config import ConfigError


@dataclass(frozen=True)
class Dynamics:
    arm_accelerations: str  # limits.yaml's acceleration set (model.ACCELERATION_SETS)
    base_acceleration_mps2: float
    base_speed_mps: float
    # where the base waits across the table (m along x from the home posture's, + towards the right
    # region): the paper does not say where its robot waits, so a calibrated regime may fit it
    base_start_x_m: float = 0.0


@dataclass(frozen=True)
class Timing:
    control_dt_s: float  # integration and control step
    latency_frames: int  # camera frames (10 ms) between computing a goal and moving on it
    anticipation_start_frame: int
    anticipation_period_frames: int
    servo_start_frame: int
    servo_period_frames: int


@dataclass(frozen=True)
class Sensing:
    noise_m: float = 0.0  # std of each coordinate of a seen ball centre
    dropout: float = 0.0  # probability that a frame's ball is not seen
    delay_frames: int = 0  # the servo at frame f sees the ball of frames <= f - delay_frames
    seed: int = 0  # of the noise and dropouts (drawn per flight from its data: the same for every controller)

    @property
    def perfect(self) -> bool:
        return self.noise_m == 0 and self.dropout == 0 and self.delay_frames == 0


@dataclass(frozen=True)
class Regime:
    name: str
    dynamics: Dynamics
    timing: Timing
    sensing: Sensing
    servo_fit: str
    calibrated: bool = False  # sensing and servo_fit come from a calibration artifact
    description: str = ""


def _section(cls, values: dict, where: str):
    names = {f.name for f in fields(cls)}
    unknown = sorted(set(values) - names)
    if unknown:
        raise ConfigError(f"{where}: unknown keys {unknown}; expected {sorted(names)}")
    try:
        return cls(**values)
    except TypeError as exc:
        raise ConfigError(f"{where}: {exc}") from exc


def parse_regime(name: str, spec: dict, seed: int = 0, calibration: dict | None = None) -> Regime:
    """The Regime of one config robot.regimes entry; `calibration` (a calibrate_regime artifact's
    `sensing`, `servo_fit` and `dynamics` knobs) replaces the config's for a calibrated regime, and must be
    given for one."""
    where = f"config robot.regimes.{name}"
    sensing = {**spec.get("sensing", {}), "seed": seed}
    servo_fit, dynamics = spec["servo_fit"], spec["dynamics"]
    if spec.get("calibrated", False):
        if calibration is None:
            raise ConfigError(f"{where} is calibrated: its calibration artifact is needed")
        sensing, servo_fit = {**calibration["sensing"], "seed": seed}, calibration["servo_fit"]
        dynamics = {**dynamics, **calibration.get("dynamics", {})}
    return Regime(name, _section(Dynamics, dynamics, f"{where}.dynamics"),
                  _section(Timing, spec["timing"], f"{where}.timing"),
                  _section(Sensing, sensing, f"{where}.sensing"), servo_fit,
                  bool(spec.get("calibrated", False)), spec.get("description", ""))


def with_sensing(regime: Regime, **knobs) -> Regime:
    """The regime with some sensing knobs (noise_m, dropout, delay_frames) replaced."""
    return replace(regime, sensing=replace(regime.sensing, **knobs))


def sense(frame_times: np.ndarray, seen: np.ndarray, sensing: Sensing) -> np.ndarray:
    """The seen ball (F, 3) at the camera frames, with the sensing's noise and dropouts (nan rows).

    The draws are seeded by the sensing's seed and the flight's first points, so every controller sees the
    same degraded flight, and they are drawn whatever the knobs (common random numbers: a change of a knob
    scales the same draws, which keeps the calibration's objective smooth)."""
    if sensing.noise_m == 0 and sensing.dropout == 0:
        return seen
    key = zlib.crc32(np.ascontiguousarray(seen[:3], float).tobytes())
    rng = np.random.default_rng([sensing.seed, key])
    noise, draws = rng.standard_normal(seen.shape), rng.random(len(seen))
    out = seen + sensing.noise_m * noise
    out[draws < sensing.dropout] = np.nan
    return out


# ---------------------------------------------------------------- the regime map's cells (regime_map.py)

SECTIONS = {"dynamics": Dynamics, "timing": Timing, "sensing": Sensing}


def axis_section(axis: str) -> str:
    """The regime section (dynamics, timing, sensing) that holds a map axis's key."""
    for section, cls in SECTIONS.items():
        if axis in {f.name for f in fields(cls)}:
            return section
    raise ValueError(f"regime map axis '{axis}' is no key of a regime's dynamics, timing or sensing")


def cell_name(base: str, point: dict) -> str:
    """A grid cell's name, e.g. paper__base_acceleration_mps2=2__latency_frames=10 (a file name)."""
    return "__".join([base, *(f"{axis}={value:g}" for axis, value in point.items())])


def map_cells(regimes: dict, named: list[str], base: str, axes: dict[str, list]) -> dict[str, dict]:
    """Cell name -> regime spec (a config robot.regimes entry): the named regimes, then the base at every
    grid point of the axes (the first axis outermost)."""
    for name in [*named, base]:
        if name not in regimes:
            raise ValueError(f"config robot.regime_map names regime '{name}', not one of {sorted(regimes)}")
    cells = {name: regimes[name] for name in named}
    for values in product(*axes.values()):
        point = dict(zip(axes, values, strict=True))
        spec = {**regimes[base], **{s: dict(regimes[base][s]) for s in SECTIONS}}
        for axis, value in point.items():
            section = axis_section(axis)
            spec[section][axis] = int(value) if isinstance(regimes[base][section].get(axis), int) else value
        cells[cell_name(base, point)] = spec | {"description": f"{base} with {point}", "grid_point": point}
    for name, spec in cells.items():  # the regime whose calibration a calibrated cell reads
        if spec.get("calibrated"):
            cells[name] = spec | {"calibration_of": name if name in named else base}
    return cells
