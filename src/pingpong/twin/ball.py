"""Ball physics of the twin: flight, table bounce, paddle impact and shot aiming (table frame, SI).

Flight: a = g - k_D |v| v + k_M (w x v) / (1 + s_M |w x v| / |v|^2), with k_D = rho A C_D / (2 m),
k_M = rho A r C_M / (2 m) and s_M = r C_M / C_L_max. That is the lift F = 0.5 rho A C_L |v|^2 along
w x v with a lift coefficient that saturates in the spin parameter S = r |w x v| / |v|^2 (the spin
across v, r|w|/|v| for pure topspin, backspin or sidespin):

    C_L(S) = C_M S / (1 + C_M S / C_L_max)

- Low spin: C_L ~ C_M S, the linear Magnus form of table-tennis robotics (Nakashima et al.,
  "Modeling of rebound phenomenon of a rigid ball with friction and elastic effects", ACC 2010;
  Tebbe et al., "Spin detection in robotic table tennis", ICRA 2020) with the twin's C_M = 0.6, kept.
  The MPI ball-gun flights fix only the product C_M |w| (realdata.fit_spin_and_drag: ~12 rev/s at
  S ~ 0.3 with this C_M), so the slope is carried over, not measured anew.
- High spin: the form and the ceiling C_L_max = 0.5 are Stepanek's wind-tunnel fit for spinning
  tennis balls, C_L = 1 / (2 + 1/S) (A. Stepanek, "The aerodynamics of tennis balls - the topspin
  lob", Am. J. Phys. 56, 138 (1988)), i.e. C_M = 1 there. Our curve lies 10-30 % below his at
  S = 0.3-3 (a smooth ball has less lift at low spin than a felt one) and is the project's choice,
  not a table-tennis measurement: no tabulated C_L(S) of 40 mm balls was at hand. Miyazaki, Sakai,
  Komatsu, Takahashi & Himeno ("Lift crisis of a spinning table tennis ball", Eur. J. Phys. 38,
  024001 (2017); flight tests of Nittaku 3-star balls, 3e4 < Re < 9e4 or ~11-34 m/s, 0 < S < 1)
  found no negative lift but a valley of C_L near S = 0.5, where at Re = 9e4 the lift all but
  vanished: not modelled, the curve here is monotone.
- The linear form (C_L_max = inf) gave C_L = 0.6 at S = 1 and grows without bound: 80 rev/s
  topspin loops (S ~ 0.8) got ~2x the Magnus force.

Drag: C_D constant. Play spans Re ~ 1e4-9e4, below a smooth sphere's drag crisis (Re ~ 3e5), where
C_D stays ~0.4-0.5 (the subcritical plateau in E. Achenbach, "Experiments on the flow past spheres at
very high Reynolds numbers", J. Fluid Mech. 54, 565 (1972)). Miyazaki et al. (2017) report C_D
changing with Re and S, but no form to use; Cross & Lindsey ("Measurements of drag and lift on
tennis balls in flight", Sports Eng. 17, 89 (2014)) found C_D independent of spin. So none here.
Spin is constant in flight (its decay time is seconds, a flight is under one).

Contacts (table and paddle) use the Nakashima 2010 impulse model for a hollow sphere
(I = 2/3 m r^2): normal restitution e, Coulomb friction mu on the contact-point slip, and the
ball leaves rolling when friction would reverse the slip (alpha capped at 2/5).

Integration is fixed-step RK4 written on Python floats: deterministic, and for a single 3-vector
ball ~10x faster per step than numpy or solve_ivp; events are located inside the step by linear
interpolation of the crossing quantity and a partial RK4 step (error ~ g dt^2 / 8 ~ 1e-6 m).
"""

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np
from scipy.optimize import brentq, least_squares, root

from pingpong.frames import (
    BALL_MASS,
    BALL_RADIUS,
    GRAVITY,
    NET_HEIGHT,
    NET_OVERHANG,
    TABLE_HALF_LENGTH,
    TABLE_HALF_WIDTH,
)

SLOWER_AIMS = (1.0, 0.6, 0.35)  # speed-hint factors a shot tries in turn when the net is in the way
FLOOR_Z = -0.76  # floor height in the table frame (regulation table height), m
ROLLING_ALPHA = 0.4  # 2/5: the slip vanishes at this friction ratio for a hollow sphere
MIN_BOUNCE_VZ = 0.05  # below this rebound speed (m/s) the ball is at rest on the table


@dataclass(frozen=True)
class BallParams:
    mass: float = BALL_MASS  # kg
    radius: float = BALL_RADIUS  # m
    air_density: float = 1.2  # kg/m^3
    # C_D, e_t, mu_t: near realdata.fit_params_to_real on the 106 MPI ball-gun flights (C_D 0.52,
    # e_t 0.93, mu_t 0.13 without spin); literature: C_D 0.4-0.5, e_t ~0.9, mu_t 0.25 (Nakashima 2010)
    drag_coefficient: float = 0.5
    magnus_coefficient: float = 0.6  # C_M: low-spin slope dC_L/dS (module docstring)
    max_lift_coefficient: float = 0.5  # C_L_max: C_L(S) levels off here (Stepanek 1988); inf: linear
    table_restitution: float = 0.92  # vertical, e_t
    table_friction: float = 0.13  # mu_t
    paddle_restitution: float = 0.85  # normal, inverted rubber
    paddle_friction: float = 0.6  # mu_p: rubber grips, so most paddle contacts end rolling

    @property
    def k_drag(self) -> float:
        """k_D = rho A C_D / (2 m), 1/m."""
        return self.air_density * math.pi * self.radius**2 * self.drag_coefficient / (2 * self.mass)

    @property
    def k_magnus(self) -> float:
        """k_M = rho A r C_M / (2 m), dimensionless."""
        return (self.air_density * math.pi * self.radius**3 * self.magnus_coefficient / (2 * self.mass))

    @property
    def magnus_saturation(self) -> float:
        """s_M = r C_M / C_L_max, m: the lift acceleration is k_M (w x v) / (1 + s_M |w x v| / |v|^2)."""
        return self.radius * self.magnus_coefficient / self.max_lift_coefficient

    def lift_coefficient(self, spin_parameter):
        """C_L(S) = C_M S / (1 + C_M S / C_L_max) for S = r |w x v| / |v|^2 (scalar or array)."""
        linear = self.magnus_coefficient * np.asarray(spin_parameter, float)
        return linear / (1 + linear / self.max_lift_coefficient)


def sample_ball_params(rng: np.random.Generator, spread: float = 0.05,
                       base: BallParams = BallParams()) -> BallParams:
    """Per-shot variation: each coefficient scaled by (1 + spread * N(0, 1)), restitutions kept < 1."""
    def scaled(value: float, upper: float = math.inf, lower: float = 0.0) -> float:
        return float(min(max(value * (1 + spread * rng.standard_normal()), lower), upper))  # np.clip: 5x

    return replace(base, drag_coefficient=scaled(base.drag_coefficient),
                   magnus_coefficient=scaled(base.magnus_coefficient),
                   table_restitution=scaled(base.table_restitution, 0.99),
                   table_friction=scaled(base.table_friction),
                   paddle_restitution=scaled(base.paddle_restitution, 0.99),
                   paddle_friction=scaled(base.paddle_friction),
                   # drawn last, so the draws above stay those of the linear-lift twin
                   max_lift_coefficient=scaled(base.max_lift_coefficient, lower=0.05))


# ---------------------------------------------------------------- contacts

def _contact(v_rel: np.ndarray, w: np.ndarray, n: np.ndarray, e: float, mu: float, r: float):
    """Nakashima 2010 impulse model on (..., 3) arrays: relative velocity and spin after contact.

    n points from the surface into the ball's side; the contact point is at -r n.
    """
    vn = np.sum(v_rel * n, axis=-1, keepdims=True)  # < 0 while approaching
    slip = v_rel - vn * n - r * np.cross(w, n)  # tangential velocity of the contact point
    slip_speed = np.linalg.norm(slip, axis=-1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        alpha = np.where(slip_speed > 0, mu * (1 + e) * np.abs(vn) / slip_speed, ROLLING_ALPHA)
    alpha = np.minimum(alpha, ROLLING_ALPHA)  # sliding stops: the ball leaves rolling
    v_out = v_rel - (1 + e) * vn * n - alpha * slip
    w_out = w + 1.5 * alpha / r * np.cross(n, slip)
    return v_out, w_out


def bounce(v, w, params: BallParams = BallParams()) -> tuple[np.ndarray, np.ndarray]:
    """Table bounce (Nakashima et al. 2010): velocity and spin (..., 3) in, the same out."""
    v, w = np.asarray(v, float), np.asarray(w, float)
    return _contact(v, w, np.array([0.0, 0.0, 1.0]), params.table_restitution, params.table_friction,
                    params.radius)


def paddle_impact(v_in, w_in, paddle_normal, paddle_velocity,
                  params: BallParams = BallParams()) -> tuple[np.ndarray, np.ndarray]:
    """Ball velocity and spin after hitting a paddle (unit face normal, face velocity in m/s).

    Same impulse model as the table, in the paddle's moving frame, with the rubber's restitution and
    friction. Both faces carry rubber, so the face the ball approaches is used whichever way the
    normal points.
    """
    v_in, w_in = np.asarray(v_in, float), np.asarray(w_in, float)
    n, v_p = np.asarray(paddle_normal, float), np.asarray(paddle_velocity, float)
    v_rel = v_in - v_p
    n = np.where(np.sum(v_rel * n, axis=-1, keepdims=True) > 0, -n, n)
    v_rel_out, w_out = _contact(v_rel, w_in, n, params.paddle_restitution, params.paddle_friction,
                                params.radius)
    return v_rel_out + v_p, w_out


def paddle_for_outgoing(v_in, v_out, params: BallParams = BallParams(),
                        w_in=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """A paddle (unit normal, velocity along that normal) that turns v_in, w_in into v_out exactly.

    With the paddle moving along its normal at speed s, paddle_impact gives
    c = v_out - v_in + alpha slip(n) = (1 + e)(s - v_in.n) n, so n = c / |c|, and the relative normal
    speed is |c| / (1 + e), which makes the sliding alpha = mu |c| / |slip| (capped at 2/5).
    The 3-equation fixed point in n is solved by scipy's root from the frictionless guess n ~ v_out - v_in.
    """
    v_in, v_out, w_in = (np.asarray(a, float) for a in (v_in, v_out, w_in))
    e, mu, r = params.paddle_restitution, params.paddle_friction, params.radius
    dv = v_out - v_in

    def c_of(n):
        slip = v_in - (v_in @ n) * n - r * np.cross(w_in, n)
        slip_speed = np.linalg.norm(slip)

        def excess(alpha):  # > 0 while friction could still take a larger share of the slip
            return mu * np.linalg.norm(dv + alpha * slip) - alpha * slip_speed

        if slip_speed == 0 or excess(ROLLING_ALPHA) >= 0:
            return dv + ROLLING_ALPHA * slip
        # excess is convex, > 0 at 0 and < 0 at 2/5: one root between
        return dv + brentq(excess, 0.0, ROLLING_ALPHA, xtol=1e-15) * slip

    sol = root(lambda n: c_of(n) / np.linalg.norm(c_of(n)) - n, dv / np.linalg.norm(dv), tol=1e-12)
    n = sol.x / np.linalg.norm(sol.x)
    c = c_of(n)
    if np.linalg.norm(c / np.linalg.norm(c) - n) > 1e-9:
        raise ValueError(f"no paddle found for v_in={v_in}, w_in={w_in}, v_out={v_out}: {sol.message}")
    speed = v_in @ n + np.linalg.norm(c) / (1 + e)
    return n, speed * n


def paddle_for_spin(v_in, w_in, v_out, w_out, params: BallParams = BallParams(),
                    start: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A paddle (unit normal, velocity) whose impact turns v_in, w_in into v_out and, as near as it can,
    w_out: how a player brushes the ball to give it spin.

    The impact fixes the spin about the normal (friction acts in the face plane) and caps the
    friction's share, so not every spin can be given: the least-squares paddle of scipy.least_squares
    over the normal and the 3-vector velocity matches v_out (weighted 10x) and the spin (as r w, m/s)
    as well as the impact allows. Starts from `start` (normal, velocity) or else paddle_for_outgoing's
    paddle (no brushing). The caller flies what paddle_impact gives for the returned paddle.
    """
    v_in, w_in, v_out, w_out = (np.asarray(a, float) for a in (v_in, w_in, v_out, w_out))
    n0, vp0 = start if start is not None else paddle_for_outgoing(v_in, v_out, params, w_in=w_in)
    r = params.radius

    def residual(x):
        n = x[:3] / np.linalg.norm(x[:3])
        v, w = paddle_impact(v_in, w_in, n, x[3:], params)
        return np.concatenate([10 * (v - v_out), r * (w - w_out)])

    sol = least_squares(residual, np.concatenate([n0, vp0]), x_scale=np.array([1, 1, 1, 10, 10, 10.0]),
                        xtol=1e-8, ftol=1e-8, max_nfev=200)
    return sol.x[:3] / np.linalg.norm(sol.x[:3]), sol.x[3:]


# ---------------------------------------------------------------- flight

class Event(NamedTuple):
    kind: str  # 'bounce', 'net', 'floor', 'stop' (the stop condition fired) or 'rest' (ball stays on table)
    time: float  # s
    position: np.ndarray  # (3,) ball centre, m
    side: str  # '+y' or '-y': the table half the ball is over


class Flight(NamedTuple):
    times: np.ndarray  # (N,) s; uniform dt, plus one extra sample at each event instant
    positions: np.ndarray  # (N, 3) m
    velocities: np.ndarray  # (N, 3) m/s
    spins: np.ndarray  # (N, 3) rad/s
    events: list[Event]


def _accel(vx, vy, vz, wx, wy, wz, kd, km, ks):
    s2 = vx * vx + vy * vy + vz * vz
    s = math.sqrt(s2)
    cx, cy, cz = wy * vz - wz * vy, wz * vx - wx * vz, wx * vy - wy * vx  # w x v
    # k_M C_L(S) / (C_M S): the saturating lift; at rest (s2 = 0) w x v is 0 as well
    lift = km / (1.0 + ks * math.sqrt(cx * cx + cy * cy + cz * cz) / s2) if s2 > 0.0 else 0.0
    return (-kd * s * vx + lift * cx, -kd * s * vy + lift * cy, -GRAVITY - kd * s * vz + lift * cz)


def rk4_step(p, v, w, kd, km, ks, h):
    """One RK4 step of (p, v) on float tuples: kd = k_D, km = k_M, ks = s_M (BallParams); w is constant in
    flight (robot.servo's fit steps it too)."""
    wx, wy, wz = w
    a1 = _accel(*v, wx, wy, wz, kd, km, ks)
    v2 = tuple(v[i] + 0.5 * h * a1[i] for i in range(3))
    a2 = _accel(*v2, wx, wy, wz, kd, km, ks)
    v3 = tuple(v[i] + 0.5 * h * a2[i] for i in range(3))
    a3 = _accel(*v3, wx, wy, wz, kd, km, ks)
    v4 = tuple(v[i] + h * a3[i] for i in range(3))
    a4 = _accel(*v4, wx, wy, wz, kd, km, ks)
    p_new = tuple(p[i] + h / 6 * (v[i] + 2 * v2[i] + 2 * v3[i] + v4[i]) for i in range(3))
    v_new = tuple(v[i] + h / 6 * (a1[i] + 2 * a2[i] + 2 * a3[i] + a4[i]) for i in range(3))
    return p_new, v_new


def stop_at_y(y_plane: float) -> Callable[[float, np.ndarray, np.ndarray], float]:
    """Stop condition for simulate_flight: the ball centre reaches the plane y = y_plane (either way)."""
    def condition(t, p, v):
        return (p[1] - y_plane) * math.copysign(1.0, -v[1])
    return condition


def _crossing(a0: float, a1: float) -> float | None:
    """Fraction of the step where a goes from > 0 to <= 0, or None."""
    if a0 > 0 >= a1:
        return a0 / (a0 - a1)
    return None


def simulate_flight(p0, v0, w0, params: BallParams = BallParams(), dt: float = 1e-3, t_max: float = 3.0,
                    stop: Callable[[float, np.ndarray, np.ndarray], float] | None = None,
                    max_bounces: int = 10) -> Flight:
    """Integrate a ball from (p0, v0, w0) at t = 0 until the floor, the net, t_max or `stop`.

    Bounces on the table surface (centre at z = r within the table's extent) apply `bounce`. The net is
    the plane y = 0 up to NET_HEIGHT over |x| <= TABLE_HALF_WIDTH + NET_OVERHANG: a ball whose centre
    crosses it below NET_HEIGHT + r is stopped there ('net'). `stop(t, p, v)` is a continuous function;
    the flight ends where it goes from > 0 to <= 0, the state refined onto that point (see stop_at_y).
    """
    kd, km, ks, r = params.k_drag, params.k_magnus, params.magnus_saturation, params.radius
    p, v = tuple(map(float, p0)), tuple(map(float, v0))
    w = tuple(map(float, w0))
    t = 0.0
    times, ps, vs, ws = [t], [p], [v], [w]
    events: list[Event] = []
    g_prev = stop(t, np.array(p), np.array(v)) if stop else 0.0

    def record(kind):
        events.append(Event(kind, t, np.array(p), "+y" if p[1] >= 0 else "-y"))

    while t < t_max - 1e-12:
        h = min(dt, t_max - t)
        p1, v1 = rk4_step(p, v, w, kd, km, ks, h)
        # candidate events in this step as (fraction, kind); the earliest one is handled
        found = []
        f = _crossing(p[2] - r, p1[2] - r)
        if f is not None:
            x, y = p[0] + f * (p1[0] - p[0]), p[1] + f * (p1[1] - p[1])
            if abs(x) <= TABLE_HALF_WIDTH and abs(y) <= TABLE_HALF_LENGTH:
                found.append((f, "bounce"))
        f = _crossing(p[1] * math.copysign(1.0, -v[1]), p1[1] * math.copysign(1.0, -v[1]))
        if f is not None:
            x, z = p[0] + f * (p1[0] - p[0]), p[2] + f * (p1[2] - p[2])
            if abs(x) <= TABLE_HALF_WIDTH + NET_OVERHANG and 0 <= z < NET_HEIGHT + r:
                found.append((f, "net"))
        f = _crossing(p[2] - FLOOR_Z - r, p1[2] - FLOOR_Z - r)
        if f is not None:
            found.append((f, "floor"))
        g1 = stop(t + h, np.array(p1), np.array(v1)) if stop else 0.0
        if stop and (f := _crossing(g_prev, g1)) is not None:
            found.append((f, "stop"))
        g_prev = g1
        if not found:
            t, p, v = t + h, p1, v1
            times.append(t), ps.append(p), vs.append(v), ws.append(w)
            continue
        f, kind = min(found)
        p, v = rk4_step(p, v, w, kd, km, ks, f * h)
        t += f * h
        if kind == "bounce":
            p = (p[0], p[1], r)  # exactly on the surface, so the next step cannot re-detect it
            times.append(t), ps.append(p), vs.append(v), ws.append(w)  # arrival state
            v_out, w_out = bounce(np.array(v), np.array(w), params)
            v, w = tuple(v_out.tolist()), tuple(w_out.tolist())
            record("bounce")
            if v[2] < MIN_BOUNCE_VZ or len(events) >= max_bounces:
                record("rest")
                break
            g_prev = stop(t, np.array(p), np.array(v)) if stop else 0.0
            times.append(t), ps.append(p), vs.append(v), ws.append(w)  # departure state
            continue
        times.append(t), ps.append(p), vs.append(v), ws.append(w)
        record(kind)
        break
    return Flight(np.array(times), np.array(ps), np.array(vs), np.array(ws), events)


# ---------------------------------------------------------------- aiming

def accel_rows(v, w, kd, km, ks):
    """The flight model of _accel on (3, N) component rows (v, w) with per-ball kd, km, ks (N,).

    The cross product is written out: np.cross costs ~10x more here.
    """
    vx, vy, vz = v
    wx, wy, wz = w
    s2 = vx * vx + vy * vy + vz * vz
    drag = kd * np.sqrt(s2)
    cx, cy, cz = wy * vz - wz * vy, wz * vx - wx * vz, wx * vy - wy * vx
    lift = km / (1 + ks * np.sqrt(cx * cx + cy * cy + cz * cz) / np.maximum(s2, 1e-300))
    out = np.empty_like(v)  # filled row by row: np.stack costs a quarter of the call
    out[0], out[1], out[2] = -drag * vx + lift * cx, -drag * vy + lift * cy, -GRAVITY - drag * vz + lift * cz
    return out


def rk4_rows(p, v, w, kd, km, ks, h):
    """One RK4 step of N balls on (3, N) rows (h a scalar or (N,) step in s): new (p, v)."""
    a1 = accel_rows(v, w, kd, km, ks)
    v2 = v + 0.5 * h * a1
    a2 = accel_rows(v2, w, kd, km, ks)
    v3 = v + 0.5 * h * a2
    a3 = accel_rows(v3, w, kd, km, ks)
    v4 = v + h * a3
    return (p + h / 6 * (v + 2 * v2 + 2 * v3 + v4),
            v + h / 6 * (a1 + 2 * a2 + 2 * a3 + accel_rows(v4, w, kd, km, ks)))


def _fly_batch(p0, v0, w, kd, km, ks, T, dt_max, r):
    """Batched RK4 (no contacts) of N balls for their own time T (N,): the end positions (N, 3) and the
    height of the ball centre above the net top + r (N,) where each first crosses y = 0 (inf: never)."""
    n = max(int(np.ceil(T.max() / dt_max)), 1)
    h = T / n
    kd, km, ks = kd.ravel(), km.ravel(), ks.ravel()
    p, v, w = p0.T.copy(), v0.T.copy(), w.T
    clearance = np.full(len(T), np.inf)
    for _ in range(n):
        p1, v = rk4_rows(p, v, w, kd, km, ks, h)
        cross = np.isinf(clearance) & ((p[1] > 0) & (p1[1] <= 0) | (p[1] < 0) & (p1[1] >= 0))
        if cross.any():
            f = p[1, cross] / (p[1, cross] - p1[1, cross])
            z_net = p[2, cross] + f * (p1[2, cross] - p[2, cross])
            clearance[cross] = z_net - NET_HEIGHT - r[cross]
        p = p1
    return p.T, clearance


def _net_flight_time(p_hit, goal, w, km, ks, T_hint, net_margin):
    """The shortest flight time (N,) s at which a parabola from p_hit to goal passes over the net with the
    margin, under gravity plus the downward Magnus acceleration of topspin w at the hinted speed: heavy
    topspin pulls a ball down, so a drive clears the net at speeds a spinless ball cannot (drag ignored)."""
    v = (goal - p_hit) / T_hint[:, None]
    g_eff = -accel_rows(v.T, w.T, np.zeros(len(v)), km.ravel(), ks.ravel())[2]  # downwards, drag-free
    # only a pull down shortens the bound: backspin keeps gravity's (the net check lengthens a flight
    # where it must; a floatier bound made pushes slower and doubled their second bounces, measured)
    g_eff = np.maximum(g_eff, GRAVITY)
    s = np.clip(p_hit[:, 1] / (p_hit[:, 1] - goal[:, 1]), 0.05, 0.95)  # flight share before the net
    height = NET_HEIGHT + goal[:, 2] + net_margin - p_hit[:, 2] * (1 - s) - goal[:, 2] * s
    return np.sqrt(np.maximum(2 * height / (g_eff * s * (1 - s)), 0.0))


def aim_shots(p_hit, target_bounce_xy, w0, params: BallParams | Sequence[BallParams] = BallParams(),
              flight_time=None, speed_hint: float = 9.0, net_margin=0.03,
              dt_max: float = 0.02, tol: float = 1e-5, strict: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Outgoing velocities (N, 3) that bounce N balls at targets (N, 2), and their flight times (N,) s.

    Shooting on the time of flight T to the bounce: for a given T the bounce point (x, y, z = r) is
    3 equations in v0, solved by Newton with a finite-difference Jacobian, all shots in one batch.
    T defaults to distance / speed_hint; shots that do not clear the net by net_margin (m) get a 10%
    longer (higher) flight and are solved again. RK4 at dt <= 20 ms is accurate to ~1e-6 m here
    (checked against simulate_flight at 1 ms). speed_hint and net_margin may be one per shot (N,): a
    margin well above the lowest clearing arc gives a higher, slower shot. strict=False gives
    NaN rows for shots that do not converge or cannot clear the net, instead of raising.
    """
    p_hit = np.atleast_2d(np.asarray(p_hit, float))
    n_shots = len(p_hit)
    target = np.atleast_2d(np.asarray(target_bounce_xy, float))
    w0 = np.broadcast_to(np.asarray(w0, float), (n_shots, 3))
    plist = [params] * n_shots if isinstance(params, BallParams) else list(params)
    kd = np.array([q.k_drag for q in plist])[:, None]
    km = np.array([q.k_magnus for q in plist])[:, None]
    ks = np.array([q.magnus_saturation for q in plist])[:, None]
    r = np.array([q.radius for q in plist])
    goal = np.column_stack([target, r])
    margin = np.broadcast_to(np.asarray(net_margin, float), (n_shots,))
    if flight_time is None:
        T = np.linalg.norm(goal[:, :2] - p_hit[:, :2], axis=1) / speed_hint
        T = np.maximum(T, 1.05 * _net_flight_time(p_hit, goal, w0, km, ks, T, margin))
    else:
        T = np.broadcast_to(np.asarray(flight_time, float), (n_shots,)).copy()
    v0 = np.empty((n_shots, 3))
    todo = np.arange(n_shots)
    eps = 1e-4  # m/s, finite-difference step: RK4 is smooth, so 1e-4 gives ~1e-8 relative accuracy
    for _ in range(12):
        p, g, T_, w_, kd_, km_, ks_ = (a[todo] for a in (p_hit, goal, T, w0, kd, km, ks))
        m = len(todo)
        # ballistic guess without drag, then Newton on the shots not yet within tol
        v = (g - p - 0.5 * np.array([0.0, 0.0, -GRAVITY]) * T_[:, None] ** 2) / T_[:, None]
        residual, clearance, live = np.full((m, 3), np.inf), np.full(m, np.inf), np.arange(m)
        for _ in range(10):
            k = len(live)
            trial = np.concatenate([v[live]] + [v[live] + eps * np.eye(3)[j] for j in range(3)])
            end, clear = _fly_batch(np.tile(p[live], (4, 1)), trial, np.tile(w_[live], (4, 1)),
                                    *(np.tile(c[live], (4, 1)) for c in (kd_, km_, ks_)),
                                    np.tile(T_[live], 4), dt_max, np.tile(r[todo][live], 4))
            end = end.reshape(4, k, 3)
            residual[live], clearance[live] = end[0] - g[live], clear[:k]
            off = np.abs(residual[live]).max(axis=1) >= tol
            if not off.any():
                break
            jac = np.stack([(end[j + 1, off] - end[0, off]) / eps for j in range(3)], axis=-1)  # (., 3, 3)
            live = live[off]
            v[live] = v[live] - np.linalg.solve(jac, residual[live][..., None])[..., 0]
        missed = ~(np.abs(residual).max(axis=1) < tol)
        if missed.any() and strict:
            raise ValueError(f"aiming did not converge: a bounce misses by {np.abs(residual).max()} m")
        v0[todo] = np.where(missed[:, None], np.nan, v)
        clear = (clearance >= margin[todo]) | missed
        todo = todo[~clear]
        if len(todo) == 0:
            return v0, T
        T[todo] *= 1.1
    if strict:
        raise ValueError(f"shots {todo.tolist()} cannot clear the net within the flight times tried")
    v0[todo] = np.nan
    return v0, T


def aim_shot(p_hit, target_bounce_xy, w0, params: BallParams = BallParams(), flight_time: float | None = None,
             speed_hint: float = 9.0, net_margin: float = 0.03) -> np.ndarray:
    """Outgoing velocity (3,) from p_hit that bounces at target_bounce_xy and clears the net (aim_shots)."""
    v0, _ = aim_shots(p_hit, target_bounce_xy, w0, params, flight_time, speed_hint, net_margin)
    return v0[0]
