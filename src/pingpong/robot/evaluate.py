"""A controller (controllers.py, the registered kinds) run over the measured test hits.

Each controller sets the speed share alpha of every control step (episode.run_episode's per-step alpha)
before the first visual-servoing goal is usable; from then on every controller servos at alpha_servo = 1.
The anticipation goal is (predicted strike x, anticipation_z): the models predict the path in the table
plane only, so the height is a fixed guess (the training hits' median strike height, simulate_robot).
"""

from dataclasses import asdict, dataclass, field

import numpy as np
import pandas as pd

from pingpong.common.config import Settings
from pingpong.curation.schemas import HIT_KEYS
from pingpong.frames import REGION_EDGE_X
from pingpong.robot.control import ControlParams
from pingpong.robot.controllers import Controller
from pingpong.robot.episode import (
    FRAME_DT,
    EpisodeParams,
    anticipation_frames,
    episode_times,
    goal_schedule,
    run_episode,
    strike_crossing,
)
from pingpong.robot.flights import HitFlight, prediction_series
from pingpong.robot.model import Robot
from pingpong.robot.regimes import Regime, parse_regime
from pingpong.robot.schemas import SIM
from pingpong.twin.ball import BallParams


@dataclass(frozen=True)
class Prediction:
    """One hit's pre-hit predictions: frames (F,) negative, strike x (F,) m, uncertainty (F,) m or None."""
    frames: np.ndarray
    strike_x: np.ndarray
    uncertainty: np.ndarray | None = None


@dataclass(frozen=True)
class SimSettings:
    episode: EpisodeParams = field(default_factory=EpisodeParams)
    anticipation_z: float = 0.15  # m, height of the anticipation goals
    # goal schedules by flight and the goals' content: the servo fits cost most of an episode, and a sweep
    # replays the same flights under every candidate (results unchanged: the schedule is deterministic)
    schedules: dict = field(default_factory=dict, compare=False, repr=False)
    # episodes by (robot, flight, schedule, per-step alpha): many candidates of a sweep, and controllers
    # that wait for the servo on a hit, move the robot identically (run_episode is deterministic)
    episodes: dict = field(default_factory=dict, compare=False, repr=False)


@dataclass(frozen=True)
class RobotSettings(Settings):
    """The robot rules' settings (config robot.*; the schema says what each means)."""

    regime_name: str  # the configured regime (config robot.regime)
    regime: dict  # its config robot.regimes entry (regimes.parse_regime)
    seed: int  # of the sensing's draws (config seed)
    alpha_grid: list[float]
    confidence_quantiles: list[float]
    max_flight_s: float

    def resolve(self, calibration: dict | None = None) -> Regime:
        """The configured Regime (a calibrated one with its calibration artifact's knobs)."""
        return parse_regime(self.regime_name, self.regime, self.seed, calibration)


def episode_params(regime: Regime, servo_ball: BallParams | None = None) -> EpisodeParams:
    """EpisodeParams of a regime's timing, sensing and servo fit (servo_ball: the model fit's ball)."""
    timing = asdict(regime.timing)
    dt = timing.pop("control_dt_s")
    return EpisodeParams(**timing, servo_fit=regime.servo_fit, servo_ball=servo_ball, sensing=regime.sensing,
                         control=ControlParams(dt=dt))


def sim_settings(regime: Regime, anticipation_z: float, servo_ball: BallParams | None = None) -> SimSettings:
    """SimSettings of a regime (simulate_robot, robot_scene and the regime map share it)."""
    return SimSettings(episode_params(regime, servo_ball), anticipation_z=float(anticipation_z))


def confidence_ramp(uncertainty: np.ndarray, u_full: float, u_zero: float) -> np.ndarray:
    """alpha in [0, 1]: 1 up to u_full, 0 from u_zero on, linear between (a step at u_full if equal)."""
    u = np.asarray(uncertainty, float)
    if u_zero <= u_full:
        return (u <= u_full).astype(float)
    return np.clip((u_zero - u) / (u_zero - u_full), 0.0, 1.0)


def step_alphas(times: np.ndarray, first_servo: float, prediction: Prediction, controller: Controller,
                params: EpisodeParams) -> np.ndarray:
    """Per-step alpha (times (S,) s) of a controller: its anticipation rule before first_servo, then
    alpha_servo. The 'latest prediction' at t is the last used one (episode.anticipation_frames)
    computed at least the latency before t."""
    prediction = used_predictions(prediction, params)
    usable = prediction.frames * FRAME_DT + params.latency_frames * FRAME_DT
    latest = np.searchsorted(usable, times + 1e-12, side="right") - 1
    has = latest >= 0
    idx = np.maximum(latest, 0)
    alpha = np.where(times < -1e-12, controller.alpha1, controller.alpha2) * has
    if len(prediction.frames) == 0:
        alpha = np.zeros_like(times)
    else:
        if controller.skip_centre:
            alpha = alpha * (np.abs(prediction.strike_x[idx]) > REGION_EDGE_X)
        if controller.confidence is not None:
            alpha = alpha * confidence_ramp(prediction.uncertainty[idx], *controller.confidence)
    alpha[times < params.anticipation_start_frame * FRAME_DT - 1e-12] = 0.0
    return np.where(times < first_servo - 1e-12, alpha, params.alpha_servo)


def used_predictions(prediction: Prediction, params: EpisodeParams) -> Prediction:
    """The prediction at the frames whose goals the robot uses (episode.anticipation_frames)."""
    used = anticipation_frames(prediction.frames, params)
    return Prediction(prediction.frames[used], prediction.strike_x[used],
                      None if prediction.uncertainty is None else prediction.uncertainty[used])


def simulate_hit(robot: Robot, flight: HitFlight, prediction: Prediction, controller: Controller,
                 settings: SimSettings = SimSettings()) -> dict:
    """run_episode of one flight under a controller; adds 'anticipated' (the robot moved before servoing)."""
    params = settings.episode
    goals = (prediction.frames, np.column_stack([prediction.strike_x,
                                                 np.full(len(prediction.frames), settings.anticipation_z)]))
    t_strike, _ = strike_crossing(flight.times, flight.positions, params.control.strike_y)
    t_end = t_strike if np.isfinite(t_strike) else flight.times[-1]
    times = episode_times(t_end, params)
    seen = (flight.seen_times, flight.seen_positions)
    # the flight object is kept in the value, so its id cannot be reused while the entry lives
    key = (id(flight), goals[0].tobytes(), goals[1].tobytes())
    cached = settings.schedules.get(key)
    if cached is not None and cached[0] is flight:
        schedule = cached[1]
    else:
        schedule = goal_schedule(*seen, t_end, goals, params)
        settings.schedules[key] = (flight, schedule)
    first_servo = schedule.first_servo
    alpha = step_alphas(times, first_servo, prediction, controller, params)
    key = (id(robot), id(flight), schedule.times.tobytes(), schedule.goals.tobytes(), first_servo,
           alpha.tobytes())
    cached = settings.episodes.get(key)
    if cached is not None and cached[0] is robot and cached[1] is flight:
        out = dict(cached[2])
    else:
        out = run_episode(robot, flight.times, flight.positions, goals, params, alpha=alpha, seen=seen,
                          schedule=schedule)
        settings.episodes[key] = (robot, flight, out)
        out = dict(out)
    out["anticipated"] = bool(np.any(alpha[times < first_servo - 1e-12] > 0))
    return out


def simulate_hits(robot: Robot, hits: pd.DataFrame, flights: list[HitFlight], predictions: list[Prediction],
                  controller: Controller, settings: SimSettings = SimSettings()) -> pd.DataFrame:
    """SIM table: one row per hit (rows of a DATASET table, with its flight and predictions, same order)."""
    rows = []
    for hit, flight, prediction in zip(hits.itertuples(index=False), flights, predictions, strict=True):
        out = simulate_hit(robot, flight, prediction, controller, settings)
        rows.append({
            "controller": controller.name, "session": hit.session, "rally": hit.rally, "hit": hit.hit,
            "region": hit.region, "strike_x": hit.strike_x, "strike_z": hit.strike_z,
            "hit_ball": out["hit"], "end_distance_m": out["end_distance_m"],
            "anticipated": out["anticipated"],
            "limits_ok": out["limits_ok"], "max_velocity_ratio": out["max_velocity_ratio"],
            "max_acceleration_ratio": out["max_acceleration_ratio"],
            "min_position_margin": out["min_position_margin"], "servo_no_estimate": out["servo_no_estimate"],
        })
    return pd.DataFrame(rows, columns=list(SIM.columns))


def hit_predictions(predictions: pd.DataFrame, hits: pd.DataFrame,
                    uncertainty: pd.DataFrame | None = None) -> list[Prediction]:
    """Prediction of every row of `hits` from a PREDICTIONS table (one model's rows) and, if given, the
    uncertainty column of an uncertainty table on the same (hit, frames_before_hit) rows."""
    xs = prediction_series(predictions, hits, "strike_x_pred")
    if uncertainty is None:
        return [Prediction(frames, x) for frames, x in xs]
    us = prediction_series(uncertainty, hits, "uncertainty")
    out = []
    for (frames, x), (u_frames, u), key in zip(xs, us, hits[HIT_KEYS].itertuples(index=False), strict=True):
        if not np.array_equal(frames, u_frames):
            raise ValueError(f"hit {tuple(key)}: predictions at frames {frames.tolist()} but uncertainties "
                             f"at {u_frames.tolist()}")
        out.append(Prediction(frames, x, u))
    return out


def bootstrap_hit_difference(hits_base: np.ndarray, hits_other: np.ndarray, rng: np.random.Generator,
                             n_boot: int = 2000, level: float = 0.95) -> tuple[float, float]:
    """Percentile interval of sum(other) - sum(base) over paired resamples of the hits (rows together)."""
    diff = hits_other.astype(int) - hits_base.astype(int)
    if len(diff) == 0:
        return np.nan, np.nan
    samples = diff[rng.integers(0, len(diff), size=(n_boot, len(diff)))].sum(axis=1)
    tail = 100 * (1 - level) / 2
    low, high = np.percentile(samples, [tail, 100 - tail])
    return float(low), float(high)
