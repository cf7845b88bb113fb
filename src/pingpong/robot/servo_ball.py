"""The visual servo's ball model: its coefficients from real flights and published ones, never the twin's.

The servo's model fit (servo.model_strike_estimate) flies a drag, Magnus and bounce model; on the twin it
would otherwise share the twin's own coefficients and so be flattered by them. Here:
  - the lift follows Stepanek's wind-tunnel fit for spinning balls, C_L = 1 / (2 + 1/S), i.e. C_M = 1 and
    C_L_max = 0.5 (A. Stepanek, "The aerodynamics of tennis balls - the topspin lob", Am. J. Phys. 56,
    138 (1988)); the twin's C_M is 0.6;
  - the drag coefficient, the table's restitution and friction are fitted on every other MPI ball-gun
    flight (the fit half, sorted by name; twin.realdata.fit_params_to_real: the work of drag, the
    vertical restitution, the Nakashima bounce's friction), with this lift;
and the servo's strike error is measured on the other half (held out), each flight placed in the table
frame (real_flight_in_table_frame).
"""

from dataclasses import asdict, replace
from functools import partial

import numpy as np

from pingpong.frames import BALL_RADIUS, STRIKE_Y
from pingpong.robot.servo import MODEL_BALL, model_strike_estimate, paper_strike_estimate
from pingpong.twin.ball import BallParams
from pingpong.twin.realdata import find_bounce, fit_params_to_real

# Stepanek 1988: C_L = 1 / (2 + 1/S) = C_M S / (1 + C_M S / C_L_max) with C_M = 1, C_L_max = 0.5
PUBLISHED_LIFT = {"magnus_coefficient": 1.0, "max_lift_coefficient": 0.5}
STRIKE_SHARE = 0.6  # the strike line lies this share of the post-bounce track's y extent past the bounce


def split_flights(flights: list[dict]) -> tuple[list[dict], list[dict]]:
    """(fit half, held-out half): alternate flights in name order."""
    ordered = sorted(flights, key=lambda f: f["name"])
    return ordered[::2], ordered[1::2]


def fit_servo_ball(flights: list[dict]) -> dict:
    """The servo's BallParams (as a dict) fitted on real flights with the published lift, and the fit's
    per-flight spread (medians and quartiles of the drag factor and restitution)."""
    base = replace(BallParams(), **PUBLISHED_LIFT)
    fit = fit_params_to_real(flights, base)
    params = fit["params"]
    return {"params": asdict(params), "n_flights": len(flights),
            "k_drag_quartiles": np.percentile(fit["k_drag"], [25, 50, 75]).tolist(),
            "restitution_quartiles": np.percentile(fit["restitution"], [25, 50, 75]).tolist(),
            "friction_with_fitted_spin": list(fit["friction_with_fitted_spin"]),
            "friction_without_spin": list(fit["friction_without_spin"])}


def real_flight_in_table_frame(flight: dict, strike_y: float = STRIKE_Y) -> tuple[np.ndarray, np.ndarray]:
    """(times (N,) s from the first sample, positions (N, 3) m) of a ball-gun flight in the table frame.

    The lab frame's axes are the table's (the ball travels towards -y); the table surface is put at the
    ball centre's lowest point at the bounce less its radius, x at the bounce, and y so that the strike
    line lies STRIKE_SHARE of the post-bounce y extent past the bounce (the flights end ~1.3 m past it,
    below the table's height beyond its edge)."""
    times, positions = flight["times"], flight["positions"]
    bounce = find_bounce(times, positions)
    y_bounce, y_end = positions[bounce, 1], positions[-1, 1]
    shift = np.array([positions[bounce, 0], y_bounce - STRIKE_SHARE * (y_bounce - y_end) - strike_y,
                      positions[bounce, 2] - BALL_RADIUS])
    return times - times[0], positions - shift


REAL_FRAMES_AFTER_LAUNCH = (10, 30, 50, 70)  # 10 ms frames: 0.1-0.5 s before the bounce (~0.6 s), 0.7 s after


def servo_fits(servo_ball: BallParams | None) -> dict:
    """The servo fits to compare: the paper's, the model fit with the servo's ball and with the twin's."""
    fits = {"paper": paper_strike_estimate,
            "model_twin_ball": partial(model_strike_estimate, params=MODEL_BALL)}
    if servo_ball is not None:
        fits["model"] = partial(model_strike_estimate, params=servo_ball)
    return fits


def describe_ball(ball: BallParams | None) -> str:
    """The servo ball's fitted and published coefficients, for captions."""
    if ball is None:
        return "none"
    return (f"C_D {ball.drag_coefficient:.3g}, e_t {ball.table_restitution:.3g}, "
            f"mu_t {ball.table_friction:.3g}, "
            f"C_M {ball.magnus_coefficient:.3g}, C_L_max {ball.max_lift_coefficient:.3g}")
