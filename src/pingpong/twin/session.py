"""A session of rallies: ball physics and both players' strokes, as ground-truth tables.

Each shot: the hitter picks a target bounce point (unevenly spread, as in the paper's data, where
more shots went to one side) and, for a share of shots, executes a fault (net, out, a short ball
that bounces twice, or misses the ball). The outgoing velocity comes from `aim_shots`; the paddle
that produces it from `paddle_for_outgoing`; the spin the rubber gives from `paddle_impact`, and
the aim is re-solved with that spin until they agree. The flight is then simulated and the
*actual* outcome (not the intent) is what the truth records. The players' strokes are planned
afterwards from all their hits, so their bodies anticipate the actual paddle pose at each hit.
"""

from dataclasses import dataclass

import numpy as np
import pandas as pd

from pingpong.frames import FRAME_NS, ROT_COLUMNS, STRIKE_Y, TABLE_HALF_LENGTH
from pingpong.twin.ball import (
    BallParams,
    Flight,
    aim_shots,
    paddle_for_outgoing,
    paddle_impact,
    sample_ball_params,
    simulate_flight,
    stop_at_y,
)
from pingpong.twin.players import bystander_joints, sample_player_style
from pingpong.twin.strokes import Hit, evaluate_player, paddle_centre_at_impact, plan_player

SIDES = {1: "near", -1: "far"}  # the player at +y is 'near', at -y 'far'
SESSION_EPOCH_NS = 1_767_225_600_000_000_000  # 2026-01-01T00:00Z; session k starts k hours later
TARGET_SIDES = (-1, 0, 1)  # target lanes in the hitter's own frame: backhand side, middle, forehand side
TARGET_WEIGHTS = (0.45, 0.20, 0.35)  # uneven, like the paper's data
TOPSPIN = 2 * np.pi * 40  # rad/s, the spin guess the aim starts from (40 rev/s)
LATE_CHANGE_RATE = 0.15  # share of hits with a late change of intent
LOWEST_HIT_Z = 0.0  # m: a ball lower than the table surface at the hitting plane is missed


@dataclass(frozen=True)
class FaultRates:
    net: float = 0.02
    out: float = 0.02
    double_bounce: float = 0.01
    miss: float = 0.02


@dataclass
class SessionTruth:
    ball: pd.DataFrame  # 1 kHz flight samples: time_ns, x, y, z, vx, vy, vz, wx, wy, wz, rally, shot
    shots: pd.DataFrame  # one row per shot
    events: pd.DataFrame  # time_ns, kind, rally, shot, side, x, y, z
    people: pd.DataFrame  # 100 Hz: time_ns, person, 75 joint columns
    paddles: pd.DataFrame  # OptiTrack rate: time_ns, player, px, py, pz, r00..r22


def _target(rng, side: int, intent: str) -> np.ndarray:
    """Bounce target (x, y) on the far half for a hitter at `side`, by intent."""
    lane = rng.choice(TARGET_SIDES, p=TARGET_WEIGHTS)
    x = float(np.clip(side * lane * 0.45 + rng.normal(0, 0.12), -0.65, 0.65))
    y = -side * rng.uniform(0.35, 1.15)
    if intent == "out":
        if rng.random() < 0.5:
            y = -side * rng.uniform(1.45, 1.75)
        else:
            x = np.sign(x or 1.0) * rng.uniform(0.85, 1.05)
    elif intent == "double_bounce":
        y = -side * rng.uniform(0.12, 0.25)
    return np.array([x, y])


def _aim(p_hit, v_in, w_in, target, params: BallParams, intent: str):
    """Outgoing velocity and spin, and the paddle (normal, velocity) that produce them."""
    speed = {"double_bounce": 3.0, "net": 7.0}.get(intent, 9.0)
    w = np.array([-np.sign(target[1]) * TOPSPIN, 0.0, 0.0])  # topspin about x for travel along y
    for _ in range(3):
        v_out, _ = aim_shots(p_hit, target, w, params, speed_hint=speed,
                             net_margin=-0.05 if intent == "net" else 0.03)
        v_out = v_out[0]
        if intent == "net":  # aim into the tape: drop the shot until it no longer clears
            v_out = v_out * np.array([1.0, 0.93, 0.75])
        normal, v_paddle = paddle_for_outgoing(v_in, v_out, params, w_in=w_in)
        v_chk, w = paddle_impact(v_in, w_in, normal, v_paddle, params)
    return v_chk, w, normal, v_paddle


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


def simulate_rallies(n_rallies: int, rates: FaultRates, rng: np.random.Generator):
    """Ball flights of all rallies: the recorder, each player's hits and tracking cues, the end time (s)."""
    rec = _Recorder()
    hits = {1: [], -1: []}
    track = {1: ([], []), -1: ([], [])}
    t = 1.0
    for rally in range(n_rallies):
        side = 1 if rally % 2 == 0 else -1  # the serve alternates
        t += rng.uniform(1.0, 2.0)
        # the server's toss: the ball drops into the hitting plane (a drive-like serve; see README)
        p = np.array([rng.uniform(-0.4, 0.4), _hitting_plane(rng, side), rng.uniform(0.15, 0.35)])
        v_in, w_in = np.array([0.0, 0.0, -1.0]), np.zeros(3)
        for shot in range(10_000):
            params = sample_ball_params(rng)
            intent = _intent(rng, rates, can_miss=shot > 0)
            if shot > 0 and p[2] < LOWEST_HIT_Z:  # the ball dropped below what a player can reach
                intent = "miss"
            if intent == "miss":  # the swing passes beside the ball, which flies on
                flight = simulate_flight(p, v_in, w_in, params, t_max=2.0)
                normal = np.array([0.0, -side, 0.0])
                miss_at = np.array([p[0] + rng.choice([-1, 1]) * rng.uniform(0.2, 0.35), p[1],
                                    max(p[2], LOWEST_HIT_Z) + 0.05])
                hits[side].append(Hit(t, miss_at, normal, 3.0 * normal, float(p[0])))
                rec.shots.append(_shot_row(rally, shot, side, t, p, v_in, v_in, w_in, normal, 3.0 * normal,
                                           intent, "miss", (np.nan, np.nan), np.full(2, np.nan), None))
                rec.flight(t, flight, rally, shot)
                t += flight.times[-1]
                break
            target = _target(rng, side, intent)
            v_out, w_out, normal, v_paddle = _aim(p, v_in, w_in, target, params, intent)
            flight = simulate_flight(p, v_out, w_out, params, t_max=3.0,
                                     stop=stop_at_y(_hitting_plane(rng, -side)))
            outcome = _outcome(flight, side)
            strike = _strike_crossing(flight, side)
            target_x = strike[0] if np.isfinite(strike[0]) else float(target[0])
            late = None
            if rng.random() < LATE_CHANGE_RATE:
                late = float(np.clip(-target_x + rng.normal(0, 0.2), -0.9, 0.9))
            hits[side].append(Hit(t, paddle_centre_at_impact(p, normal), normal, v_paddle, target_x, late))
            track[-side][0].append(t + 0.15)
            track[-side][1].append(float(flight.positions[-1, 0]))
            rec.shots.append(_shot_row(rally, shot, side, t, p, v_in, v_out, w_out, normal, v_paddle,
                                       intent, outcome, strike, target, late))
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
    return rec, hits, track, t


def _shot_row(rally, shot, side, t, p, v_in, v_out, w_out, normal, v_paddle, intent, outcome, strike,
              target, late) -> dict:
    row = {"rally": rally, "shot": shot, "hitter": SIDES[side], "side": side,
           "t_hit_ns": int(round(t * 1e9)), "intent": intent, "outcome": outcome,
           "strike_x": strike[0], "strike_z": strike[1], "target_x": target[0], "target_y": target[1],
           "late_change": late is not None, "prepared_x": np.nan if late is None else late}
    for name, vec in (("hit", p), ("v_in", v_in), ("v_out", v_out), ("w_out", w_out),
                      ("paddle_normal", normal), ("paddle_v", v_paddle)):
        row.update({f"{name}_{a}": float(vec[i]) for i, a in enumerate("xyz")})
    return row


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


def simulate_session(n_rallies: int, rates: FaultRates, rng: np.random.Generator, optitrack_hz: float = 240.0,
                     session_index: int = 0, bystander_rate: float = 0.2) -> SessionTruth:
    """Ground truth of one session: ball, shots, events, people at 100 Hz, paddles at optitrack_hz."""
    rec, hits, track, t_end = simulate_rallies(n_rallies, rates, rng)
    t_end += 1.0
    epoch = SESSION_EPOCH_NS + session_index * 3_600_000_000_000
    frames = np.arange(0, int(t_end * 1e9), FRAME_NS, dtype=np.int64)
    opt = np.arange(0, int(t_end * 1e9), int(round(1e9 / optitrack_hz)), dtype=np.int64)
    people, paddles = [], []
    for side in (1, -1):
        plan = plan_player(side, hits[side], sample_player_style(rng), rng,
                           track_times=np.array(track[side][0]), track_x=np.array(track[side][1]))
        body = evaluate_player(plan, frames / 1e9)
        people.append(_people_frame(frames + epoch, SIDES[side], body.joints))
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
                        pd.concat(paddles, ignore_index=True))


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
