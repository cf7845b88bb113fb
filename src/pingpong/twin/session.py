"""A session of rallies: ball physics and both players' strokes, as ground-truth tables.

Each shot: the hitter makes the four decisions of `pingpong.twin.repertoire` (stroke, intent, late
change, execution) and, for a share of shots, executes a fault (net, out, a short ball that bounces
twice, or misses the ball). The outgoing velocity comes from `aim_shots` with the stroke's spin; the
paddle that brushes the ball for that spin from `paddle_for_spin`; the spin the rubber actually gives
from `paddle_impact`, and the shot is re-aimed with it. The flight is then simulated and the *actual*
outcome (not the intent) is what the truth records. The players' strokes are planned afterwards from
all their hits, so their bodies show each decision from the time it was made.

The serve's toss (`serve_toss`, config twin.serve_toss; off by default, and then the twin's bytes are those
without it). Off, a serve's ball appears at the hit point falling at 1 m/s and nothing is recorded before the
hit. On, each serve is preceded by the ball in play's recorded toss, as ITTF Laws 2.06.01-2.06.04 have it:
it leaves the server's open palm (behind the end line, above the playing surface), is projected near
vertically upwards without spin, rises TOSS_RISE_M above the palm (>= 16 cm), and is struck as it falls, so
its velocity at the hit (the serve's v_in) is the fall from the apex. The ball is in play from its release
(Law 2.05.01: "from the last moment at which it is stationary on the palm of the free hand before being
intentionally projected"), so the truth records it from there, under the rally's id and shot TOSS_SHOT (no
row of the shots table has it: a shot's flight stays hit to hit). The palm is TOSS_PALM_BACK_M farther from
the table than the serve's hit point, the ball thrown a little forwards onto it (7.6 degrees from the
vertical in the median, 21.8 at most, 24 tosses of seeds 3 and 4: "near vertically"), so the hit point and
its draws are those of the toss off. Its flight time is added to the pause before the serve: the rally's
first sample is the release, still 0.5-1.0 s after the previous rally's last.
Toss heights: no measured distribution was found (searched: serve toss height, kinematic serve studies);
the Laws set the 16 cm floor, and a coach's account (L. Hodges, USA Table Tennis, 1997/2013: "two-foot
tosses" beside high tosses of 10-20 feet from the ground) the common range; TOSS_RISE_M is chosen within
it, without the high tosses (1-2 s in the air, beyond the twin's compressed pauses). The palm's height
over the table, TOSS_PALM_Z_M, is chosen. The server's free hand is at the palm: simulate_session bends
the free arm (players.free_hand_to) so that its hand reaches under the ball TOSS_REACH_S before the
release, stays still TOSS_STILL_S (the Laws' stationary palm) and drops back over TOSS_DROP_S after.
Failure mode: the body is planned from the paddle's hits alone, so the palm can lie beyond the free arm;
the hand then stops at the nearest point it reaches, arm straight. Measured on 24 tosses (simulate_session
seeds 3 and 4, 12 rallies each; the hand's centre at the release, as tests/test_twin_toss.py measures it):
67 % within 2 cm, the gap's median 1 mm, 90th percentile 18 cm, largest 24 cm; directly under the hit point
(no TOSS_PALM_BACK_M) half the palms were out of reach, by up to 36 cm. Per-frame cost: none (the twin's
truth tables; a toss is ~0.5 s of 1 kHz RK4 samples, a few shooting rounds).
Measured on the tiny run with the room (config/test/tiny.yaml over config/config.yaml, twin.serve_toss true,
12 tosses, 625 frames of each of 3 cameras; reports.perception_accuracy.detection_rows on the truth rows
of the toss frames): track's one-view recall of the tossed ball 99.1-99.8 %, multi-view
99.8-100 %, false detections in toss frames 0-0.16 %; under 1 m/s (the apex, 226 frames a camera) one-view
99.5-100 %, multi-view 100 %. New false detections the toss brings: the server's free hand reaching for
the palm (a moving skin disc), 10 frames of camera 1. Curation finds no serve as a hit (the toss is
thrown towards the table, so y never turns at the serve), as with the toss off.
"""

from dataclasses import dataclass

import numpy as np
import pandas as pd

from pingpong.frames import FRAME_NS, GRAVITY, ROT_COLUMNS, STRIKE_Y, TABLE_HALF_LENGTH
from pingpong.twin.ball import (
    SLOWER_AIMS,
    BallParams,
    Event,
    Flight,
    aim_shots,
    paddle_for_spin,
    paddle_impact,
    simulate_flight,
    stop_at_y,
)
from pingpong.twin.players import bystander_joints, free_hand_to, sample_player_style
from pingpong.twin.repertoire import (
    ShotContext,
    ShotTiming,
    Tactics,
    choose_stroke,
    draw_execution,
    draw_intent,
    draw_late,
    executed_shot,
    sample_tactics,
    target_strike_x,
)
from pingpong.twin.strokes import Hit, evaluate_player, paddle_centre_at_impact, plan_player, smoothstep

SIDES = {1: "near", -1: "far"}  # the player at +y is 'near', at -y 'far'
SESSION_EPOCH_NS = 1_767_225_600_000_000_000  # 2026-01-01T00:00Z; session k starts k hours later
MIN_STROKE_GAP = 0.62  # s: a ball back sooner after a player's last stroke is missed (strokes.py needs 0.6)
LOWEST_HIT_Z = -0.2  # m: a ball lower at the hitting plane is missed (players lift balls below the table)
TOSS_SHOT = -1  # the ball table's shot id of a serve's toss (the serve is shot 0)
TOSS_RISE_M = (0.16, 0.60)  # the toss's rise over the palm: the Laws' 16 cm to a two-foot toss (docstring)
TOSS_PALM_Z_M = (0.05, 0.35)  # the palm over the table top (above the playing surface: Law 2.06.04; chosen)
TOSS_PALM_BACK_M = (0.10, 0.30)  # the palm behind the hit point, towards the server (chosen: docstring)
TOSS_MIN_FALL_M = 0.02  # the ball falls at least this far from the apex before the hit ("as it falls")
PALM_DEPTH_M = 0.045  # the hand's centre under the ball on the palm: twin.render's hand disc radius
TOSS_REACH_S, TOSS_STILL_S, TOSS_DROP_S = 0.4, 0.1, 0.3  # the free hand's moves around a toss (chosen)


@dataclass(frozen=True)
class FaultRates:
    net: float = 0.02
    out: float = 0.02
    double_bounce: float = 0.01
    miss: float = 0.02


@dataclass(frozen=True)
class Toss:
    """A serve's toss: when the ball leaves the palm (s, session clock before the epoch), where, by whom."""

    t_release: float
    palm: np.ndarray  # (3,) the ball's centre at the release, m
    side: int  # the server's


@dataclass
class SessionTruth:
    ball: pd.DataFrame  # 1 kHz flight samples: time_ns, x, y, z, vx, vy, vz, wx, wy, wz, rally, shot
    shots: pd.DataFrame  # one row per shot
    events: pd.DataFrame  # time_ns, kind, rally, shot, side, x, y, z
    people: pd.DataFrame  # 100 Hz: time_ns, person, 75 joint columns
    paddles: pd.DataFrame  # OptiTrack rate: time_ns, player, px, py, pz, r00..r22
    records: list  # ShotRecord of every good shot, for the oracle (times before the epoch)


def _fault_target(rng, target: np.ndarray, side: int, fault: str) -> np.ndarray:
    """The bounce point a fault puts the ball at instead of the target (x, y)."""
    x, y = target
    if fault == "out":
        if rng.random() < 0.5:
            y = -side * rng.uniform(1.45, 1.75)
        else:
            x = np.sign(x or 1.0) * rng.uniform(0.85, 1.05)
    elif fault == "double_bounce":
        y = -side * rng.uniform(0.12, 0.25)
    return np.array([x, y])


def _aim(p_hit, v_in, w_in, target, w_wanted, speed, params: BallParams, fault: str, net_height: float):
    """Outgoing velocity and spin, and the paddle (normal, velocity) that produce them; the ball centre
    crosses the net at least net_height (m) over its top edge (a shot into the net: 5 cm under it).

    Aimed with the spin wanted, the paddle brushes the ball for it (paddle_for_spin); the shot is
    re-aimed with the spin the impact actually gives and the paddle solved again, so the spin flown is
    the paddle's, and the bounce lands within millimetres of the target.
    """
    w, paddle = w_wanted, None
    for _ in range(2):
        v_out = _aim_slower(p_hit, target, w, params, speed,
                            -0.05 if fault == "net" else net_height - params.radius)
        if fault == "net":  # aim into the tape: drop the shot until it no longer clears
            v_out = v_out * np.array([1.0, 0.93, 0.75])
        paddle = paddle_for_spin(v_in, w_in, v_out, w, params, start=paddle)
        v_chk, w = paddle_impact(v_in, w_in, *paddle, params)
    return v_chk, w, paddle[0], paddle[1]


def _aim_slower(p_hit, target, w, params: BallParams, speed: float, net_margin: float) -> np.ndarray:
    """aim_shots' velocity, at a lower speed hint (a higher, slower ball) when the net is in the way."""
    for factor in SLOWER_AIMS:
        try:
            return aim_shots(p_hit, target, w, params, speed_hint=speed * factor, net_margin=net_margin)[0][0]
        except ValueError:
            continue
    raise ValueError(f"no shot from {p_hit} clears the net to {target} with spin {w} rad/s")


def _outcome(flight: Flight, side: int) -> str:
    """What happened to a shot by the hitter at `side`, from its flight's events."""
    kinds = [(e.kind, e.side) for e in flight.events if e.kind != "rest"]
    far = "-y" if side > 0 else "+y"
    if any(k == "net" for k, _ in kinds):
        return "net"
    bounces = [s for k, s in kinds if k == "bounce"]
    if not bounces or bounces[0] != far:
        return "out"
    if len(bounces) >= 2:
        return "double_bounce"
    return "ok" if kinds[-1][0] == "stop" else "out"


def _strike_crossing(flight: Flight, side: int) -> tuple[float, float]:
    """(x, z) where the flight crosses the far strike line y = -side * 1.40 m, or NaN."""
    y = flight.positions[:, 1] * side  # the hitter's own frame: the ball travels towards -y
    i = np.flatnonzero((y[:-1] > STRIKE_Y) & (y[1:] <= STRIKE_Y))
    if len(i) == 0:
        return np.nan, np.nan
    i = i[0]
    f = (y[i] - STRIKE_Y) / (y[i] - y[i + 1])
    p = flight.positions[i] + f * (flight.positions[i + 1] - flight.positions[i])
    return float(p[0]), float(p[2])


def _intent(rng, rates: FaultRates, can_miss: bool) -> str:
    kinds = ["net", "out", "double_bounce"] + (["miss"] if can_miss else [])
    p = np.array([getattr(rates, k) for k in kinds])
    u = rng.random()
    i = np.searchsorted(np.cumsum(p), u, side="right")
    return kinds[i] if i < len(kinds) else "ok"


class _Recorder:
    """Collects the ball samples, shots and events of a session as rows."""

    def __init__(self):
        self.ball, self.shots, self.events = [], [], []
        self.tosses: list[Toss] = []

    def flight(self, t0: float, flight: Flight, rally: int, shot: int):
        n = len(flight.times)
        self.ball.append(np.column_stack([
            np.round((t0 + flight.times) * 1e9), flight.positions, flight.velocities, flight.spins,
            np.full(n, rally), np.full(n, shot)]))
        for e in flight.events:
            if e.kind in ("bounce", "net", "floor"):
                self.event(t0 + e.time, e.kind, rally, shot, e.position, e.side)

    def event(self, t: float, kind: str, rally: int, shot: int, position, side: str):
        self.events.append({"time_ns": int(round(t * 1e9)), "kind": kind, "rally": rally, "shot": shot,
                            "side": side, "x": position[0], "y": position[1], "z": position[2]})


def _meet_at_top(flight: Flight, receiver: int) -> Flight:
    """The flight up to where the receiver meets it: the top of its bounce, between 2 cm behind the strike
    line and where the flight was stopped (players take the ball near its peak, the fastest and flattest
    ball they can hit from there). A flight that ended otherwise (net, floor, no bounce) is left whole."""
    if not flight.events or flight.events[-1].kind != "stop":
        return flight
    bounces = [e.time for e in flight.events if e.kind == "bounce"]
    y = flight.positions[:, 1] * receiver
    band = (flight.times > (bounces[-1] if bounces else np.inf)) & (y >= -STRIKE_Y + 0.02)
    if not band.any():
        return flight
    k = int(np.flatnonzero(band)[np.argmax(flight.positions[band, 2])])
    events = [e for e in flight.events if e.time < flight.times[k]]
    events.append(Event("stop", float(flight.times[k]), flight.positions[k], flight.events[-1].side))
    cut = slice(0, k + 1)
    return Flight(flight.times[cut], flight.positions[cut], flight.velocities[cut], flight.spins[cut], events)


def _dead_ball(flight: Flight, outcome: str, params: BallParams) -> Flight | None:
    """The flight of a ball after the rally ended, to the floor (None if it is already there)."""
    last = flight.events[-1].kind if flight.events else ""
    if last in ("floor", "rest"):
        return None
    p, v, w = flight.positions[-1], flight.velocities[-1], flight.spins[-1]
    if outcome == "net":  # the tape takes nearly all of the speed; the ball drops on its side
        v = v * np.array([0.2, -0.15, 0.0])
        p = p + np.array([0.0, 0.01 * np.sign(v[1]), 0.0])  # off the net plane, so it is not met again
    return simulate_flight(p, v, w, params, t_max=2.0)


def _hitting_plane(rng, side: int) -> float:
    """y of the plane where a player at `side` meets the ball, behind the end line."""
    return side * (TABLE_HALF_LENGTH + rng.uniform(0.05, 0.35))


@dataclass(frozen=True)
class ShotRecord:
    """A good shot's decisions as the twin made them: what the oracle re-draws from."""

    rally: int
    shot: int
    t_hit: float  # s, session clock before the epoch
    tactics: Tactics
    ctx: ShotContext
    timing: ShotTiming
    intent: dict  # draw_intent's, one draw
    final: dict  # draw_late's on it
    execution: dict  # draw_execution's, one draw
    spin_ratio: float  # |spin the paddle gave| / |spin wanted|, both across the paddle's normal
    strike_x: float  # m, where the flight crossed the far strike line


def _decide(rng, tactics: Tactics, ctx: ShotContext, ball: BallParams):
    """The four decisions of a shot, in the order they are made (pingpong.twin.repertoire)."""
    timing = choose_stroke(rng, tactics, ctx)
    intent = draw_intent(rng, tactics, timing, ctx, 1)
    final = draw_late(rng, tactics, timing, ctx, intent)
    execution = draw_execution(rng, tactics, timing, ctx, 1, ball)
    return timing, intent, final, execution


def launch_speed(rise: float, ball: BallParams) -> float:
    """Upward speed (m/s) that lifts a spinless ball `rise` m against gravity and quadratic drag:
    with dv/dt = -g - k_D v^2 the apex is ln(1 + k_D v0^2 / g) / (2 k_D) above the start."""
    k = ball.k_drag
    return float(np.sqrt(GRAVITY * np.expm1(2 * k * rise) / k))


def toss_flight(rng: np.random.Generator, p_hit: np.ndarray, side: int, ball: BallParams) -> Flight:
    """A serve's toss from the palm up and down onto p_hit, falling there (module docstring): the palm
    TOSS_PALM_Z_M over the table and TOSS_PALM_BACK_M farther from the table than p_hit (towards the
    server at `side`), the rise TOSS_RISE_M over the palm and, where the hit point is high, enough to fall
    TOSS_MIN_FALL_M onto it. The horizontal launch speed is found by shooting: the drag that slows it
    depends on the whole speed, so it is corrected by the miss over the flight time until within 0.1 mm."""
    palm_z = rng.uniform(*TOSS_PALM_Z_M)
    rise = rng.uniform(max(TOSS_RISE_M[0], p_hit[2] + TOSS_MIN_FALL_M - palm_z), TOSS_RISE_M[1])
    palm = np.array([p_hit[0], p_hit[1] + side * rng.uniform(*TOSS_PALM_BACK_M), palm_z])

    def falling_onto_hit(t, p, v):  # > 0 until the falling ball reaches the hit's height
        return p[2] - p_hit[2] if v[2] < 0 else 1.0

    v0 = np.array([0.0, 0.0, launch_speed(rise, ball)])
    for _ in range(10):
        flight = simulate_flight(palm, v0, np.zeros(3), ball, t_max=3.0, stop=falling_onto_hit)
        miss = p_hit[:2] - flight.positions[-1, :2]
        if np.abs(miss).max() < 1e-4:
            return flight
        v0[:2] += miss / flight.times[-1]
    raise ValueError(f"no toss from {palm} falls onto {p_hit}")


def simulate_rallies(n_rallies: int, rates: FaultRates, rng: np.random.Generator, homoscedastic: bool = False,
                     ball: BallParams = BallParams(), serve_toss: bool = False):
    """Ball flights of all rallies: the recorder, each player's hits and tracking cues, the end time (s),
    the good shots' decisions (ShotRecord) and both players' tactics. serve_toss: each serve is preceded by
    its toss (module docstring; the recorder's tosses list them)."""
    rec = _Recorder()
    hits = {1: [], -1: []}
    track = {1: ([], []), -1: ([], [])}
    tactics = {s: sample_tactics(rng, homoscedastic) for s in (1, -1)}
    records = []
    t = 1.0
    for rally in range(n_rallies):
        side = 1 if rally % 2 == 0 else -1  # the serve alternates
        # the pause before the serve: real ones last seconds (fetching a ball); compressed to 0.5-1.0 s,
        # longer than the curation's rally gap (0.4 s), to spend the cameras' frames on play: 10 % fewer
        # frames than 1-2 s pauses, the same shots (one uniform draw either way)
        t += rng.uniform(0.5, 1.0)
        # the server's toss: the ball drops into the hitting plane (a drive-like serve; see README)
        p = np.array([rng.uniform(-0.4, 0.4), _hitting_plane(rng, side), rng.uniform(0.15, 0.35)])
        v_in, w_in = np.array([0.0, 0.0, -1.0]), np.zeros(3)
        if serve_toss:  # the toss recorded from the palm, its time added to the pause
            toss = toss_flight(rng, p, side, ball)
            rec.flight(t, toss, rally, TOSS_SHOT)
            rec.tosses.append(Toss(t, toss.positions[0], side))
            t += toss.times[-1]
            p, v_in = toss.positions[-1], toss.velocities[-1]
        last_hit = {1: -np.inf, -1: -np.inf}
        for shot in range(10_000):
            ctx = ShotContext(p, v_in, w_in, side, serve=shot == 0)
            timing, intent, final, execution = _decide(rng, tactics[side], ctx, ball)
            params = execution["params"][0]
            fault = _intent(rng, rates, can_miss=shot > 0)
            late_ball = shot > 0 and (p[2] < LOWEST_HIT_Z or t - last_hit[side] < MIN_STROKE_GAP)
            if fault == "miss" or late_ball:  # the swing passes beside the ball, which flies on
                flight = simulate_flight(p, v_in, w_in, params, t_max=2.0)
                normal = np.array([0.0, -side, 0.0])
                if not t - last_hit[side] < MIN_STROKE_GAP:  # too soon after their last stroke: no swing
                    miss_at = np.array([p[0] + rng.choice([-1, 1]) * rng.uniform(0.2, 0.35), p[1],
                                        max(p[2], LOWEST_HIT_Z) + 0.05])
                    hits[side].append(Hit(t, miss_at, normal, 3.0 * normal, float(p[0])))
                rec.shots.append(_shot_row(rally, shot, side, t, p, v_in, v_in, w_in, normal, 3.0 * normal,
                                           "miss", "miss", (np.nan, np.nan), np.full(2, np.nan), None,
                                           tactics[side], ctx, timing))
                rec.flight(t, flight, rally, shot)
                t += flight.times[-1]
                break
            target, speed, w_wanted, net_height = executed_shot(ctx, timing, intent, final, execution)
            target = _fault_target(rng, target[0], side, fault)
            speed = {"double_bounce": 3.0, "net": 7.0}.get(fault, speed[0])
            v_out, w_out, normal, v_paddle = _aim(p, v_in, w_in, target, w_wanted[0], speed, params, fault,
                                                  float(net_height[0]))
            back = rng.uniform(0.15, 0.5)  # how far behind the end line the receiver can take the ball
            flight = _meet_at_top(simulate_flight(p, v_out, w_out, params, t_max=3.0,
                                                  stop=stop_at_y(-side * (TABLE_HALF_LENGTH + back))), -side)
            outcome = _outcome(flight, side)
            strike = _strike_crossing(flight, side)
            target_x = strike[0] if np.isfinite(strike[0]) else float(target[0])
            late = None
            if final["late"][0]:  # the body prepared the first intent's direction
                late = float(target_strike_x(p, intent["target"], STRIKE_Y * side)[0])
            if outcome == "ok":
                across = np.eye(3) - np.outer(normal, normal)  # the spin the paddle's friction gives
                ratio = float(np.linalg.norm(across @ w_out) / np.linalg.norm(across @ w_wanted[0]))
                records.append(ShotRecord(rally, shot, t, tactics[side], ctx, timing, intent, final,
                                          execution, ratio, strike[0]))
            hits[side].append(Hit(t, paddle_centre_at_impact(p, normal), normal, v_paddle, target_x, late,
                                  timing.stroke, timing.reveal_s, timing.late_s))
            last_hit[side] = t
            track[-side][0].append(t + 0.15)
            track[-side][1].append(float(flight.positions[-1, 0]))
            rec.shots.append(_shot_row(rally, shot, side, t, p, v_in, v_out, w_out, normal, v_paddle,
                                       fault, outcome, strike, target, late, tactics[side], ctx, timing))
            rec.event(t, "hit", rally, shot, p, "+y" if side > 0 else "-y")
            rec.flight(t, flight, rally, shot)
            t_end = t + flight.times[-1]
            if outcome != "ok":
                dead = _dead_ball(flight, outcome, params)
                if dead is not None:
                    rec.flight(t_end, dead, rally, shot)
                    t_end += dead.times[-1]
                t = t_end
                break
            t, p = t_end, flight.positions[-1]
            v_in, w_in = flight.velocities[-1], flight.spins[-1]
            side = -side
    return rec, hits, track, t, records, tactics


def _shot_row(rally, shot, side, t, p, v_in, v_out, w_out, normal, v_paddle, intent, outcome, strike,
              target, late, tactics: Tactics, ctx: ShotContext, timing: ShotTiming) -> dict:
    row = {"rally": rally, "shot": shot, "hitter": SIDES[side], "side": side,
           "t_hit_ns": int(round(t * 1e9)), "intent": intent, "outcome": outcome,
           "strike_x": strike[0], "strike_z": strike[1], "target_x": target[0], "target_y": target[1],
           "late_change": late is not None, "prepared_x": np.nan if late is None else late,
           "stroke": timing.stroke, "deception": tactics.deception, "pressure": ctx.pressure,
           "reveal_s": timing.reveal_s, "late_s": timing.late_s}
    for name, vec in (("hit", p), ("v_in", v_in), ("v_out", v_out), ("w_out", w_out),
                      ("paddle_normal", normal), ("paddle_v", v_paddle)):
        row.update({f"{name}_{a}": float(vec[i]) for i, a in enumerate("xyz")})
    return row


def session_epoch_ns(session_index: int) -> int:
    """Camera-clock time (ns) of a session's t = 0: session k starts k hours after SESSION_EPOCH_NS."""
    return SESSION_EPOCH_NS + session_index * 3_600_000_000_000


def _bystander_mask(times: np.ndarray, rate: float, rng) -> np.ndarray:
    """Frames where a bystander is in the room: a few intervals covering about `rate` of the time."""
    present = np.zeros(len(times), bool)
    if rate <= 0:
        return present
    span, covered = times[-1] - times[0], 0.0
    while covered < rate * span:
        length = rng.uniform(5.0, 20.0)
        start = rng.uniform(times[0], max(times[-1] - length, times[0]))
        present |= (times >= start) & (times < start + length)
        covered = present.mean() * span
    return present


def toss_hand_weights(times: np.ndarray, tosses: list[Toss]) -> tuple[np.ndarray, np.ndarray]:
    """Where the server's free hand goes for its tosses: per time (s), the hand's centre under the ball at
    the release (T, 3) and how far it has moved there from its own place (T,), 0 to 1 (module docstring)."""
    target, weight = np.zeros((len(times), 3)), np.zeros(len(times))
    for toss in tosses:
        still = toss.t_release - TOSS_STILL_S
        w = np.where(times < toss.t_release, smoothstep(times, still - TOSS_REACH_S, still),
                     1 - smoothstep(times, toss.t_release, toss.t_release + TOSS_DROP_S))
        take = w > weight
        weight[take] = w[take]
        target[take] = toss.palm - np.array([0.0, 0.0, PALM_DEPTH_M])
    return target, weight


def simulate_session(n_rallies: int, rates: FaultRates, rng: np.random.Generator, optitrack_hz: float = 240.0,
                     session_index: int = 0, bystander_rate: float = 0.2,
                     homoscedastic: bool = False, serve_toss: bool = False) -> SessionTruth:
    """Ground truth of one session: ball, shots, events, people at 100 Hz, paddles at optitrack_hz.

    homoscedastic: the control twin (config/twin_homoscedastic.yaml), where when a shot's intent
    shows and how often it changes late do not depend on anything a model could see. serve_toss: each serve
    is preceded by its toss from the server's free hand (module docstring).
    """
    rec, hits, track, t_end, records, _ = simulate_rallies(n_rallies, rates, rng, homoscedastic,
                                                           serve_toss=serve_toss)
    t_end += 1.0
    epoch = session_epoch_ns(session_index)
    frames = np.arange(0, int(t_end * 1e9), FRAME_NS, dtype=np.int64)
    opt = np.arange(0, int(t_end * 1e9), int(round(1e9 / optitrack_hz)), dtype=np.int64)
    people, paddles = [], []
    for side in (1, -1):
        plan = plan_player(side, hits[side], sample_player_style(rng), rng,
                           track_times=np.array(track[side][0]), track_x=np.array(track[side][1]))
        body = evaluate_player(plan, frames / 1e9)
        joints = body.joints
        tosses = [toss for toss in rec.tosses if toss.side == side]
        if tosses:
            joints = free_hand_to(joints, plan.dims, plan.style.handedness,
                                  *toss_hand_weights(frames / 1e9, tosses))
        people.append(_people_frame(frames + epoch, SIDES[side], joints))
        pad = evaluate_player(plan, opt / 1e9)
        paddles.append(pd.DataFrame({
            "time_ns": opt + epoch, "player": SIDES[side],
            **{f"p{a}": pad.paddle_pos[:, i] for i, a in enumerate("xyz")},
            **dict(zip(ROT_COLUMNS, pad.paddle_rot.reshape(-1, 9).T, strict=True))}))
    extra = bystander_joints(frames / 1e9, rng)
    extra[~_bystander_mask(frames / 1e9, bystander_rate, rng)] = np.nan
    people.append(_people_frame(frames + epoch, "bystander", extra))
    ball = pd.DataFrame(np.vstack(rec.ball), columns=["time_ns", "x", "y", "z", "vx", "vy", "vz",
                                                       "wx", "wy", "wz", "rally", "shot"])
    ball = ball.astype({"time_ns": np.int64, "rally": np.int32, "shot": np.int32})
    ball["time_ns"] += epoch
    ball = ball.drop_duplicates("time_ns", keep="last").reset_index(drop=True)
    shots = pd.DataFrame(rec.shots)
    shots["t_hit_ns"] += epoch
    events = pd.DataFrame(rec.events).sort_values("time_ns", kind="stable").reset_index(drop=True)
    events["time_ns"] += epoch
    return SessionTruth(ball, shots, events, pd.concat(people, ignore_index=True),
                        pd.concat(paddles, ignore_index=True), records)


def _people_frame(time_ns: np.ndarray, person: str, joints: np.ndarray) -> pd.DataFrame:
    cols = {f"j{k:02d}_{a}": joints[:, k, i] for k in range(joints.shape[1]) for i, a in enumerate("xyz")}
    return pd.DataFrame({"time_ns": time_ns, "person": person, **cols})


def ball_positions_at(ball: pd.DataFrame, time_ns: np.ndarray) -> np.ndarray:
    """True ball centre (N, 3) at any times, interpolated within a rally's flight; NaN between rallies."""
    t = np.asarray(time_ns, np.int64)
    src = ball["time_ns"].to_numpy()
    out = np.column_stack([np.interp(t, src, ball[a].to_numpy()) for a in "xyz"])
    spans = ball.groupby("rally")["time_ns"].agg(["min", "max"]).to_numpy()
    inside = ((t[:, None] >= spans[:, 0]) & (t[:, None] <= spans[:, 1])).any(axis=1)
    out[~inside] = np.nan
    return out
