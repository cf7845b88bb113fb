"""Real ball flights (MPI Tuebingen ball gun) and flight statistics shared by real and twin flights.

The statistics use positions only around the bounce (quadratic fits on windows either side, skipping
the samples next to the contact): the recorded velocities come from a filter that smears the
bounce over ~2 samples, and twin flights are compared the same way.
"""

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.integrate import cumulative_trapezoid

from pingpong.frames import GRAVITY
from pingpong.twin.ball import BallParams, bounce

FIT_WINDOW = 0.15  # s of flight either side of the bounce used for the in/out velocities
CONTACT_GAP = 0.025  # s skipped next to the bounce (filter smear, contact duration)
MIN_SAMPLES = 20
DEFAULT_PARAMS = BallParams()


def _sample_times(positions: np.ndarray, velocities: np.ndarray) -> np.ndarray:
    """Sample times (s). The files carry none; |dp| / |v| per step shows a 5.45 ms tick: most steps take
    two ticks (the README's ~10.9 ms), some one, three or four. Each step is snapped to a whole number
    of ticks, so the recorded (filtered, bounce-smeared) speed only has to be right to +-25%."""
    step = np.linalg.norm(np.diff(positions, axis=0), axis=1)
    speed = 0.5 * (np.linalg.norm(velocities[:-1], axis=1) + np.linalg.norm(velocities[1:], axis=1))
    raw = step / speed
    typical = np.median(raw)
    tick = np.median(raw[np.abs(raw - typical) < 0.25 * typical]) / 2
    return np.concatenate([[0.0], np.cumsum(np.maximum(np.round(raw / tick), 1) * tick)])


def load_real_flights(folder) -> list[dict]:
    """Every *.json flight in folder: name, times (s), positions (N, 3) m, velocities (N, 3) m/s, and
    dt (s), the median sampling interval. Repeated rows are dropped."""
    paths = sorted(Path(folder).glob("*.json"))
    if not paths:
        raise FileNotFoundError(f"no *.json ball flights in {folder}")
    flights = []
    for path in paths:
        try:
            data = json.loads(path.read_text())
        except json.JSONDecodeError as exc:
            raise ValueError(f"{path}: not valid JSON ({exc})") from exc
        rows = data.get("ob") if isinstance(data, dict) else None
        if rows is None:
            raise ValueError(f"{path}: expected an object with key 'ob' (rows of x, y, z, vx, vy, vz)")
        try:
            samples = np.asarray(rows, dtype=float)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{path}: 'ob' is not a numeric table ({exc})") from exc
        if samples.ndim != 2 or samples.shape[1] != 6 or len(samples) < MIN_SAMPLES:
            raise ValueError(f"{path}: 'ob' has shape {samples.shape}, expected (N >= {MIN_SAMPLES}, 6)")
        bad = np.flatnonzero(~np.isfinite(samples).all(axis=1))
        if len(bad):
            raise ValueError(f"{path}: row {bad[0]} of 'ob' is not finite: {samples[bad[0]].tolist()}")
        # a repeated row is a frame the tracker did not update: keep its first occurrence
        repeated = np.flatnonzero(np.all(np.diff(samples[:, :3], axis=0) == 0, axis=1)) + 1
        samples = np.delete(samples, repeated, axis=0)
        times = _sample_times(samples[:, :3], samples[:, 3:])
        flights.append({"name": path.stem, "times": times, "positions": samples[:, :3],
                        "velocities": samples[:, 3:], "dt": float(np.median(np.diff(times)))})
    return flights


def find_bounce(times: np.ndarray, positions: np.ndarray, span: float = 0.03) -> int:
    """Index of the bounce: the lowest local minimum of z where the vertical velocity, as z's slope over
    `span` s either side, turns from - to +. The slope of z, not the recorded velocity, because the
    recorded one comes from a filter that turns it ~3 samples late."""
    z = positions[:, 2]
    i = np.arange(1, len(z) - 1)
    minima = i[(z[i] <= z[i - 1]) & (z[i] <= z[i + 1])]
    before = np.searchsorted(times, times[minima] - span)
    after = np.minimum(np.searchsorted(times, times[minima] + span), len(z) - 1)
    candidates = minima[(z[before] > z[minima]) & (z[after] > z[minima])]
    if len(candidates) == 0:
        raise ValueError("no bounce: z has no minimum where the vertical velocity turns upwards")
    return int(candidates[np.argmin(z[candidates])])


def _window_fit(times, positions, lo, hi, k_drag):
    """Polynomial coefficients (3 rows of [a/2, v, p] in powers of t) of the ball over [lo, hi] s.

    The acceleration is not fitted but set to gravity plus drag at the window's mean velocity: fitted
    curvature on ~12 noisy samples swings the velocity extrapolated to the bounce by +-0.5 m/s,
    while the model's acceleration is right to a few %. Magnus (unknown spin) is left out.
    """
    keep = (times >= lo) & (times <= hi)
    if keep.sum() < 4:
        raise ValueError(f"fewer than 4 samples in [{lo:.3f}, {hi:.3f}] s around the bounce")
    t, p = times[keep], positions[keep]
    mean_velocity = np.array([np.polyfit(t, p[:, k], 1)[0] for k in range(3)])
    accel = np.array([0.0, 0.0, -GRAVITY]) - k_drag * np.linalg.norm(mean_velocity) * mean_velocity
    return np.array([[0.5 * accel[k], *np.polyfit(t, p[:, k] - 0.5 * accel[k] * t**2, 1)] for k in range(3)])


def _log_rate(times, values) -> float:
    """Relative rate of change of values (1/s) from a straight-line fit of their logarithm."""
    return float(np.polyfit(times, np.log(values), 1)[0])


def flight_stats(times, positions, velocities, bounce_index: int | None = None,
                 params: BallParams = DEFAULT_PARAMS) -> dict:
    """Flight and bounce statistics of one flight (real or twin); angles in rad, rates in %/s.

    speed_loss_pct_per_s: loss rate of the energy speed sqrt(|v|^2 + 2 g (z - z_bounce)) before the
    bounce, which removes gravity's exchange so only air drag shows (Magnus does no work);
    hspeed_loss_pct_per_s: the same for the horizontal speed. In/out velocities at the bounce come
    from fits to the positions of FIT_WINDOW s either side (_window_fit, params' drag), evaluated at
    the bounce time, where the two fitted z parabolas meet.
    """
    times, positions, velocities = (np.asarray(a, float) for a in (times, positions, velocities))
    i = find_bounce(times, positions) if bounce_index is None else bounce_index
    t_i = times[i]
    pre = _window_fit(times, positions, t_i - FIT_WINDOW, t_i - CONTACT_GAP, params.k_drag)
    post = _window_fit(times, positions, t_i + CONTACT_GAP, t_i + FIT_WINDOW, params.k_drag)
    roots = np.roots(np.polysub(pre[2], post[2]))
    near = roots[np.isreal(roots)].real
    near = near[np.abs(near - t_i) <= 2 * CONTACT_GAP]
    t_b = float(near[np.argmin(np.abs(near - t_i))]) if len(near) else float(t_i)
    v_in = np.array([np.polyval(np.polyder(c), t_b) for c in pre])
    v_out = np.array([np.polyval(np.polyder(c), t_b) for c in post])

    flying = times <= t_i - CONTACT_GAP
    speed = np.linalg.norm(velocities[flying], axis=1)
    energy_speed = np.sqrt(speed**2 + 2 * GRAVITY * (positions[flying, 2] - positions[i, 2]))
    h_in, h_out = np.hypot(*v_in[:2]), np.hypot(*v_out[:2])
    return {
        "bounce_index": i,
        "bounce_time": t_b,
        "bounce_position": np.array([np.polyval(c, t_b) for c in pre]),
        "speed_loss_pct_per_s": -100 * _log_rate(times[flying], energy_speed),
        "hspeed_loss_pct_per_s": -100 * _log_rate(times[flying], np.hypot(*velocities[flying, :2].T)),
        "speed_in": float(np.linalg.norm(v_in)),
        "speed_out": float(np.linalg.norm(v_out)),
        "speed_ratio": float(np.linalg.norm(v_out) / np.linalg.norm(v_in)),
        "angle_in": float(np.arctan2(-v_in[2], h_in)),
        "angle_out": float(np.arctan2(v_out[2], h_out)),
        "hspeed_ratio": float(h_out / h_in),
        "restitution_z": float(-v_out[2] / v_in[2]),
        "v_in": v_in,
        "v_out": v_out,
    }


# quantity -> (label, unit, scale from the SI value in flight_stats)
TABLE_QUANTITIES = {
    "speed_loss_pct_per_s": ("energy-speed loss before the bounce", "%/s", 1.0),
    "hspeed_loss_pct_per_s": ("horizontal speed loss before the bounce", "%/s", 1.0),
    "speed_in": ("speed before the bounce", "m/s", 1.0),
    "speed_out": ("speed after the bounce", "m/s", 1.0),
    "speed_ratio": ("speed ratio out/in", "", 1.0),
    "angle_in": ("incidence angle to the table", "deg", 180 / np.pi),
    "angle_out": ("rebound angle to the table", "deg", 180 / np.pi),
    "hspeed_ratio": ("horizontal velocity ratio out/in", "", 1.0),
    "restitution_z": ("vertical restitution", "", 1.0),
}


def compare_flights_table(twin_stats: list[dict], real_stats: list[dict]) -> pd.DataFrame:
    """Median and IQR (q75 - q25) of each statistic for twin and real flights, side by side."""
    rows = []
    for key, (label, unit, scale) in TABLE_QUANTITIES.items():
        row = {"quantity": label, "unit": unit}
        for name, stats in (("twin", twin_stats), ("real", real_stats)):
            values = scale * np.array([s[key] for s in stats], dtype=float)
            q25, q50, q75 = np.percentile(values, [25, 50, 75])
            row |= {f"{name}_median": q50, f"{name}_iqr": q75 - q25}
        rows.append(row)
    table = pd.DataFrame(rows)
    table.attrs |= {"twin_n": len(twin_stats), "real_n": len(real_stats)}
    return table


def fit_spin_and_drag(times, positions, velocities, bounce_index: int, params: BallParams = DEFAULT_PARAMS):
    """Drag factor k_D (1/m) and spin w (3,) rad/s that explain one flight's path before the bounce.

    k_D from the work of drag: d/dt(|v|^2/2 + g z) = -k_D |v|^3 (gravity is conservative, Magnus does no
    work), a one-parameter least squares. Then, with k_D known and w constant, integrating the flight
    equation gives v(t) - v(0) - g t + k_D int |v| v dt = k_M w x (p(t) - p(0)): linear in (v(0), w).
    The spin's size scales with 1 / C_M, which real flights alone cannot separate. The fit is linear in
    the lift; the spin is then scaled up to the saturating lift's (_saturated_spin).
    """
    flying = times <= times[bounce_index] - CONTACT_GAP
    t, p, v = times[flying] - times[0], positions[flying], velocities[flying]
    speed = np.linalg.norm(v, axis=1)
    energy = 0.5 * speed**2 + GRAVITY * p[:, 2]
    work = cumulative_trapezoid(speed**3, t, initial=0)
    k_drag = float(-np.sum((energy - energy[0]) * work) / np.sum(work**2))
    drag_integral = cumulative_trapezoid(k_drag * speed[:, None] * v, t, axis=0, initial=0)
    lhs = v - np.array([0.0, 0.0, -GRAVITY]) * t[:, None] + drag_integral  # = v(0) + k_M w x dp
    dp = p - p[0]
    # w x dp = -[dp]_x w
    skew = np.zeros((len(t), 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -dp[:, 2], dp[:, 1], -dp[:, 0]
    skew -= skew.transpose(0, 2, 1)
    design = np.concatenate([np.tile(np.eye(3), (len(t), 1)), -params.k_magnus * skew.reshape(-1, 3)], axis=1)
    solution, *_ = np.linalg.lstsq(design, lhs.reshape(-1), rcond=None)
    return k_drag, _saturated_spin(solution[3:], v.mean(axis=0), params)


def _saturated_spin(linear_spin: np.ndarray, velocity: np.ndarray, params: BallParams) -> np.ndarray:
    """The spin whose saturating lift (ball.py) equals the linear fit's k_M w x v at the flight's mean
    velocity: the lift factor 1 / (1 + s_M |w x v| / |v|^2) inverted for the spin across v."""
    speed = np.linalg.norm(velocity)
    across = np.linalg.norm(np.cross(linear_spin, velocity)) / speed  # |w_lin| across v, rad/s
    # a linear lift beyond what the saturating one can give (factor < 0.2) is taken as 5x the linear spin
    return linear_spin / max(1.0 - params.magnus_saturation * across / speed, 0.2)


def fit_params_to_real(flights: list[dict], base: BallParams = DEFAULT_PARAMS) -> dict:
    """BallParams (drag coefficient, table restitution, table friction) that best explain real flights.

    Per flight: k_D and spin from fit_spin_and_drag, the in/out velocities from flight_stats. Then the
    drag coefficient is the median k_D converted to C_D, the restitution the median vertical one, and
    the friction the mu whose Nakashima bounce (with each flight's fitted spin) best predicts the
    measured horizontal outgoing velocities (least squares over a grid), once with the fitted spins
    and once without spin; the better of the two is used. Returns the params, the per-flight fits and
    both friction fits as (mu, RMSE of the outgoing horizontal velocity in m/s).
    """
    k_drag, spins, v_in, v_out, restitution = [], [], [], [], []
    for f in flights:
        stats = flight_stats(f["times"], f["positions"], f["velocities"], params=base)
        kd, w = fit_spin_and_drag(f["times"], f["positions"], f["velocities"], stats["bounce_index"], base)
        k_drag.append(kd), spins.append(w), v_in.append(stats["v_in"]), v_out.append(stats["v_out"])
        restitution.append(stats["restitution_z"])
    k_drag, spins, v_in, v_out = map(np.array, (k_drag, spins, v_in, v_out))
    drag_coefficient = float(np.median(k_drag) * 2 * base.mass / (base.air_density * np.pi * base.radius**2))
    e = float(np.median(restitution))
    grid = np.linspace(0.0, 0.6, 121)

    def friction_fit(spin):
        errors = []
        for mu in grid:
            trial = replace(base, table_restitution=e, table_friction=mu)
            predicted, _ = bounce(v_in, spin, trial)
            errors.append(np.sqrt(np.mean(np.sum((predicted[:, :2] - v_out[:, :2]) ** 2, axis=1))))
        return float(grid[np.argmin(errors)]), float(np.min(errors))

    mu_spin, rmse_spin = friction_fit(spins)
    mu_no_spin, rmse_no_spin = friction_fit(np.zeros_like(spins))
    params = replace(base, drag_coefficient=drag_coefficient, table_restitution=e,
                     table_friction=mu_spin if rmse_spin < rmse_no_spin else mu_no_spin)
    return {"params": params, "k_drag": k_drag, "spins": spins, "restitution": np.array(restitution),
            "friction_with_fitted_spin": (mu_spin, rmse_spin),
            "friction_without_spin": (mu_no_spin, rmse_no_spin)}
