"""Table-tennis strokes of the twin's players: a plan per player, evaluated at any sample times.

A stroke drives a few smooth signals (MidHip, trunk twist and lean, paddle centre and paddle
rotation), each a cubic Hermite spline through keyframes: start (ready), top of the backswing, hit,
end of the follow-through, back at ready. The skeleton follows from them (`players.pose_joints`); the
playing wrist sits `paddle_reach` behind the paddle centre along the handle, so the hand-paddle
distance is constant and the paddle is where the hand puts it.

Anticipation: every stroke is planned three times, for a *neutral* aim (the middle of the far end),
for the *prepared* target and for the *actual* target, and the signals are blended
    x(t) = x_neutral + w(t) (x_prepared - x_neutral) + w_late(t) (x_actual - x_prepared)
where w rises smoothly from 0 at `intent_lead` before the hit to 1 at the hit. Before that the
pose carries no information on the target; at the hit it is fully determined. Prepared = actual
unless the hit has a late change of intent: then the body (MidHip, trunk) goes for the prepared
target and only the paddle turns to the actual one, w_late rising over the last `late_window`.
All three plans hit the same paddle position at t_hit and w = w_late = 1 there, so the paddle's
position, rotation and velocity at the hit are exactly the requested ones.

paddle_rot convention: the paddle's rigid body frame (what motion capture measures), columns are
its axes in the table frame: column 0 = from the handle to the tip of the blade (the direction from
the wrist to the paddle centre), column 2 = outward normal of the forehand face, column 1 = column 2
x column 0. A forehand hits with the forehand face (hitting normal = column 2), a backhand with the
other one (hitting normal = -column 2); `StrokeTrajectory.forehand` tells which.
"""

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy.interpolate import CubicHermiteSpline
from scipy.spatial.transform import Rotation

from pingpong.frames import BALL_RADIUS, STRIKE_Y, TABLE_HALF_LENGTH
from pingpong.twin.players import (
    FLOOR_Z,
    BodyDims,
    J,
    PlayerStyle,
    body_dims,
    player_base,
    pose_joints,
    rot_x,
    rot_z,
)
from pingpong.twin.repertoire import STROKES

# Signal channels of a stroke spline.
ROOT, TWIST, LEAN, POS, ROT = slice(0, 3), 3, 4, slice(5, 8), slice(8, 11)
N_CHANNELS = 11
MOVE_TIME = 0.4  # s, a tracking side-step between strokes


@dataclass(frozen=True)
class Hit:
    """One hit of a player, as the ball physics wants it."""

    t_hit: float  # s
    paddle_pos: np.ndarray  # (3,) paddle centre at impact (`paddle_centre_at_impact`)
    normal: np.ndarray  # (3,) hitting-face normal at impact (normalised here)
    velocity: np.ndarray  # (3,) paddle-centre velocity at impact, m/s
    target_x: float  # x where the ball will cross the far strike line (y = -side * 1.40 m)
    late_change: float | None = None  # target x the body prepares for before the wrist turns late
    stroke: str = "drive"  # a key of repertoire.STROKES: its swing length and trunk rotation
    intent_lead: float | None = None  # s, the target shows from this long before the hit (None: the style's)
    late_window: float | None = None  # s, a late change turns the wrist in this last stretch (None: style's)


@dataclass(frozen=True)
class StrokeTrajectory:
    times: np.ndarray  # (T,) s
    joints: np.ndarray  # (T, 25, 3) BODY_25 keypoints, table frame
    paddle_pos: np.ndarray  # (T, 3) paddle centre
    paddle_rot: np.ndarray  # (T, 3, 3) paddle axes as columns (see module docstring)
    forehand: tuple[bool, ...]  # per planned hit in time order; backhand: hitting normal = -paddle_rot[:, 2]


@dataclass(frozen=True)
class _StrokePlan:
    t_hit: float
    t_start: float
    t_end: float
    intent_start: float
    late_start: float
    spline: CubicHermiteSpline  # signals for the neutral, prepared and actual aims side by side
    rot_ref: np.ndarray  # rotation channels are rotation vectors relative to this
    forehand: bool


@dataclass(frozen=True)
class PlayerPlan:
    """Everything random about a player's motion, drawn once; `evaluate_player` samples it anywhere."""

    side: int
    style: PlayerStyle
    dims: BodyDims
    base: np.ndarray
    home: np.ndarray  # (3,) ready MidHip position before any tracking
    track_times: np.ndarray  # (K,) s, the player starts moving towards track_x[i] at track_times[i]
    track_x: np.ndarray  # (K,) m, ready MidHip x aimed at
    sway: np.ndarray  # (3, 4) amplitude (m, rad), frequency (Hz), phase of idle sway in x, y, z, twist
    paddle_ready: np.ndarray  # (3,) paddle centre relative to the MidHip, table frame
    rot_ready: np.ndarray  # (3, 3)
    strokes: tuple


def paddle_centre_at_impact(ball_pos: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Paddle centre for a ball touching the face with this normal: one ball radius behind the ball."""
    n = np.asarray(normal, float)
    return np.asarray(ball_pos, float) - BALL_RADIUS * n / np.linalg.norm(n)


def paddle_frame(normal: np.ndarray, handle_hint: np.ndarray) -> np.ndarray:
    """Paddle rotation with column 2 = normal and column 0 as close to handle_hint as it can be."""
    n = normal / np.linalg.norm(normal)
    tip = handle_hint - (handle_hint @ n) * n
    if np.linalg.norm(tip) < 1e-3:  # hint along the normal: any blade direction in the face plane
        tip = np.cross(n, [1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.cross(n, [0.0, 1.0, 0.0])
    tip /= np.linalg.norm(tip)
    return np.column_stack([tip, np.cross(n, tip), n])


def smoothstep(t: np.ndarray, start: float, end: float) -> np.ndarray:
    """0 before `start`, 1 after `end`, and between them the cubic 3s^2 - 2s^3 of the elapsed share s: a move
    that starts and ends at rest."""
    s = np.clip((t - start) / max(end - start, 1e-9), 0.0, 1.0)
    return s * s * (3 - 2 * s)


def _ready(plan: PlayerPlan, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ready-position signals (T, 11) and their time derivatives; rotation channels unused (zero)."""
    val, der = np.zeros((len(t), N_CHANNELS)), np.zeros((len(t), N_CHANNELS))
    # Lateral tracking: a smoothstep move of MOVE_TIME towards each new x, from where the last one
    # ended. Moves already over add their whole step; only the few under way are evaluated.
    steps = np.diff(np.concatenate([[plan.home[0]], plan.track_x]))
    done = np.searchsorted(plan.track_times + MOVE_TIME, t, side="right")
    started = np.searchsorted(plan.track_times, t, side="right")
    val[:, 0] = plan.home[0] + np.concatenate([[0.0], np.cumsum(steps)])[done]
    for j in range(int((started - done).max(initial=0))):
        i = np.minimum(done + j, len(steps) - 1)
        s = np.where(done + j < started, np.clip((t - plan.track_times[i]) / MOVE_TIME, 0.0, 1.0), 0.0)
        val[:, 0] += steps[i] * s * s * (3 - 2 * s)
        der[:, 0] += steps[i] * 6 * s * (1 - s) / MOVE_TIME
    val[:, 1:3] = plan.home[1:]
    amp, freq, phase = plan.sway
    arg = 2 * np.pi * freq * t[:, None] + phase
    idle, d_idle = amp * np.sin(arg), amp * 2 * np.pi * freq * np.cos(arg)
    val[:, [0, 1, 2, TWIST]] += idle
    der[:, [0, 1, 2, TWIST]] += d_idle
    val[:, LEAN] = plan.style.lean
    val[:, POS] = val[:, ROOT] + plan.paddle_ready
    der[:, POS] = der[:, ROOT]
    return val, der


def _alpha(p: np.ndarray, target_x: float, side: int, forward: np.ndarray) -> float:
    """Horizontal angle (rad, positive to the player's left) from straight ahead to the target."""
    d = np.array([target_x - p[0], -side * abs(STRIKE_Y) - p[1]])
    return float(np.arctan2(forward[0] * d[1] - forward[1] * d[0], forward[:2] @ d))


def _plan_stroke(plan: PlayerPlan, hit: Hit, t_prev: float, t_next: float,
                 rng: np.random.Generator) -> _StrokePlan:
    style, dims, base, side = plan.style, plan.dims, plan.base, plan.side
    h, k = style.handedness, style.height / 1.75
    right, fwd, up = base.T
    t_hit = float(hit.t_hit)
    p = np.asarray(hit.paddle_pos, float)
    n_act = np.asarray(hit.normal, float) / np.linalg.norm(hit.normal)
    v_act = np.asarray(hit.velocity, float)
    speed = float(np.linalg.norm(v_act))
    t_start = max(t_hit - style.prep_time, 0.5 * (t_prev + t_hit))
    t_end = min(t_hit + style.recovery_time, 0.5 * (t_hit + t_next))
    kind = STROKES[hit.stroke]
    # The swing covers at most ~0.5 m (k-scaled) at the paddle's speed, but lasts >= 60 ms however fast the
    # paddle brushes; a long stroke (a loop's) shortens when the hits come fast, 50 ms staying for the
    # ready phases.
    swing = min(max(min(style.swing_time * kind.swing_scale * (1 + 0.1 * rng.standard_normal()),
                        2 * 0.5 * k * kind.swing_scale / max(speed, 1e-6)), 0.06), t_hit - t_start - 0.05)
    follow = min(max(min(style.follow_time * kind.swing_scale * (1 + 0.1 * rng.standard_normal()),
                         2 * 0.35 * k * kind.swing_scale / max(speed, 1e-6)), 0.06), t_end - t_hit - 0.05)
    knots = np.array([t_start, t_hit - swing, t_hit, t_hit + follow, t_end])
    if np.any(np.diff(knots) < 0.05):
        raise ValueError(f"hit at t={t_hit:.3f} s: strokes of one player overlap (previous hit "
                         f"{t_prev:.3f} s, next {t_next:.3f} s); keep them >= 0.25 s apart")
    ready_val, ready_der = _ready(plan, knots[[0, 2, 4]])
    lateral = h * (p - ready_val[1, ROOT]) @ right
    forehand = bool(lateral > style.forehand_threshold)
    fh = 1.0 if forehand else -1.0

    # Per-stroke jitter, shared by the three aims so that it carries nothing about the target.
    jitter = style.noise * rng.standard_normal((6, 3))
    twist_jitter = 4 * style.noise * rng.standard_normal(3)
    reach = dims.arm_reach * (0.78 + 0.03 * rng.standard_normal())
    shoulder_dir = base @ (np.array([h * 0.5, 0.6, -0.55]) if forehand else np.array([-h * 0.25, 0.7, -0.6]))
    shoulder_dir = shoulder_dir + 2 * jitter[5]
    handle_hint = base @ (np.array([h * 0.85, 0.35, -0.25]) if forehand else np.array([-h * 0.85, 0.35, 0.1]))
    # The face turns back about the vertical in the backswing and through after the hit.
    turn_back, turn_through = rot_z(np.array(-h * fh * 0.5)), rot_z(np.array(h * fh * 0.6))
    jitter_rot = Rotation.from_rotvec(4 * jitter[2:4]).as_matrix()
    lean_hit = style.lean + 0.1
    twist_back0, twist_hit0, twist_ft0 = ((np.array([-0.75, -0.1, 0.55]) if forehand
                                           else np.array([0.45, 0.05, -0.3])) * h * kind.twist_scale
                                          + twist_jitter)
    g = style.intent_gain

    alpha_act = _alpha(p, hit.target_x, side, fwd)
    prepared = hit.target_x if hit.late_change is None else hit.late_change
    aims = (_alpha(p, 0.0, side, fwd), _alpha(p, prepared, side, fwd), alpha_act)
    rots = [paddle_frame(fh * rot_z(np.array(a - alpha_act)) @ n_act, handle_hint) for a in aims]
    rot_ref = rots[0]
    values, slopes, key_rots = [], [], []
    for i, (alpha, r_hit) in enumerate(zip(aims, rots, strict=True)):
        v = rot_z(np.array(alpha - alpha_act)) @ v_act
        val, der = np.zeros((5, N_CHANNELS)), np.zeros((5, N_CHANNELS))
        val[[0, 4]], der[[0, 4]] = ready_val[[0, 2]], ready_der[[0, 2]]
        twists = np.array([twist_back0 - 0.4 * g * alpha, twist_hit0 + 0.6 * g * alpha,
                           twist_ft0 + 0.8 * g * alpha])
        if i == 2:  # the body stays with the prepared target
            body = slice(0, POS.start)
            val[1:4, body], der[1:4, body] = values[1][1:4, body], slopes[1][1:4, body]
        else:
            root_hit = _root_at_hit(dims, base, h, p - dims.paddle_reach * r_hit[:, 0], shoulder_dir,
                                    reach, twists[1], lean_hit, style.crouch)
            shift = 0.04 * k * fwd  # weight from the back foot to the front foot
            val[1:4, ROOT] = root_hit - shift, root_hit, root_hit + shift
            der[2, ROOT] = 2 * shift / (swing + follow)
            val[1:4, TWIST], val[1:4, LEAN] = twists, lean_hit
            der[2, TWIST] = (twists[2] - twists[0]) / (swing + follow)
        r_back, r_ft = jitter_rot[0] @ turn_back @ r_hit, jitter_rot[1] @ turn_through @ r_hit
        back = p - v * swing / 2 + (-0.08 * up if forehand else -0.05 * fwd) * k + jitter[0]
        follow_end = p + v * follow / 2 + (0.12 * up - h * fh * 0.2 * right) * k + jitter[1]
        shoulders = _shoulder(dims, base, h, val[[1, 3]])
        val[1:4, POS] = (_within_reach(dims, shoulders[0], back, r_back[:, 0]), p,
                         _within_reach(dims, shoulders[1], follow_end, r_ft[:, 0]))
        der[2, POS] = v
        key_rots += [r_back, r_hit, r_ft]
        values.append(val)
        slopes.append(der)
    # Rotation channels: rotation vectors relative to rot_ref, all keyframes in one call.
    q = Rotation.from_matrix(rot_ref.T @ np.array(key_rots + [plan.rot_ready])).as_rotvec()
    for i, (val, der) in enumerate(zip(values, slopes, strict=True)):
        val[[0, 4], ROT] = q[-1]
        val[1:4, ROT] = q[3 * i:3 * i + 3]
        der[2, ROT] = (val[3, ROT] - val[1, ROT]) / (swing + follow)
    spline = CubicHermiteSpline(knots, np.concatenate(values, 1), np.concatenate(slopes, 1))
    lead = style.intent_lead if hit.intent_lead is None else hit.intent_lead
    window = style.late_window if hit.late_window is None else hit.late_window
    return _StrokePlan(t_hit, t_start, t_end, t_hit - lead,
                       t_hit - window if hit.late_change is not None else t_hit - lead,
                       spline, rot_ref, forehand)


def _shoulder(dims: BodyDims, base: np.ndarray, h: int, sig: np.ndarray) -> np.ndarray:
    """Playing shoulder (N, 3) for signal rows (N, 11)."""
    trunk = base @ rot_z(sig[:, TWIST]) @ rot_x(-sig[:, LEAN])
    return sig[:, ROOT] + trunk @ np.array([h * dims.shoulder_half, 0.0, dims.torso])


def _within_reach(dims: BodyDims, shoulder: np.ndarray, paddle: np.ndarray, tip: np.ndarray) -> np.ndarray:
    """Paddle keyframe pulled towards the shoulder until the wrist is within 90 % of the arm's length."""
    arm = paddle - dims.paddle_reach * tip - shoulder
    dist = np.linalg.norm(arm)
    return paddle - arm * max(0.0, 1 - 0.9 * dims.arm_reach / dist)


def _root_at_hit(dims: BodyDims, base: np.ndarray, h: int, wrist: np.ndarray, shoulder_dir: np.ndarray,
                 reach: float, twist: float, lean: float, crouch: float) -> np.ndarray:
    """MidHip at the hit that puts the playing shoulder `reach` from the wrist along shoulder_dir.

    The MidHip height stays within a plausible crouch; the vertical offset that leaves is taken up
    by the horizontal distance, keeping the wrist in reach.
    """
    trunk = base @ rot_z(np.array(twist)) @ rot_x(np.array(-lean))
    shoulder_off = trunk @ np.array([h * dims.shoulder_half, 0.0, dims.torso])
    d = shoulder_dir / np.linalg.norm(shoulder_dir)
    standing = FLOOR_Z + dims.hip_height
    root_z = np.clip(wrist[2] - reach * d[2] - shoulder_off[2],
                     FLOOR_Z + 0.6 * dims.hip_height, standing - (1 - crouch) * dims.hip_height * 0.5)
    dz = wrist[2] - (root_z + shoulder_off[2])
    if abs(dz) > 0.95 * dims.arm_reach:
        raise ValueError(f"paddle at z={wrist[2]:.2f} m is out of the player's reach")
    reach = float(np.clip(reach, abs(dz) / 0.95, 0.95 * dims.arm_reach))
    horiz = np.array([d[0], d[1], 0.0]) / np.linalg.norm(d[:2])
    shoulder = wrist - np.sqrt(reach**2 - dz**2) * horiz
    shoulder[2] = wrist[2] - dz
    return shoulder - shoulder_off


def plan_player(side: int, hits: Sequence[Hit], style: PlayerStyle, rng: np.random.Generator,
                track_times: np.ndarray | None = None, track_x: np.ndarray | None = None) -> PlayerPlan:
    """Plan one player's motion over a rally: ready position, lateral tracking, one stroke per hit.

    side: +1 / -1, the end of the table (y > 0 / y < 0) the player stands at. hits: this player's hits,
    any order, >= 0.25 s apart. track_times/track_x: at track_times[i] (s) the player starts moving
    towards the ball's expected lateral position track_x[i] (m; e.g. where the ball will cross this end
    line, known from the opponent's hit); the player follows a style-dependent fraction of it.
    """
    dims = body_dims(style)
    base = player_base(side)
    h, k = style.handedness, style.height / 1.75
    right = base[:, 0]
    home_x = float((-h * style.home_offset * right)[0])
    home = np.array([home_x, side * (TABLE_HALF_LENGTH + style.distance_behind),
                     FLOOR_Z + style.crouch * dims.hip_height])
    tt = np.asarray([] if track_times is None else track_times, float)
    tx = np.asarray([] if track_x is None else track_x, float)
    order = np.argsort(tt)
    tx = np.clip(home_x + style.tracking_gain * (tx[order] - home_x), -0.9, 0.9)
    sway = np.stack([np.array([0.01, 0.01, 0.006, 0.03]),  # m, m, m, rad
                     rng.uniform([0.4, 0.4, 1.5, 0.3], [1.0, 1.0, 2.5, 0.7]), rng.uniform(0, 2 * np.pi, 4)])
    rot_ready = paddle_frame(base @ np.array([-h * 1.0, 0.3, 0.0]), base @ np.array([-h * 0.1, 0.85, 0.45]))
    plan = PlayerPlan(side, style, dims, base, home, tt[order], tx, sway,
                      base @ (np.array([h * 0.18, 0.40, 0.30]) * k), rot_ready, ())
    hits = sorted(hits, key=lambda hit: hit.t_hit)
    t_hits = [-np.inf] + [hit.t_hit for hit in hits] + [np.inf]
    strokes = tuple(_plan_stroke(plan, hit, t_hits[i], t_hits[i + 2], rng) for i, hit in enumerate(hits))
    return replace(plan, strokes=strokes)


def evaluate_player(plan: PlayerPlan, times: np.ndarray) -> StrokeTrajectory:
    """The planned motion sampled at any times (s): skeleton, paddle position and rotation."""
    t = np.asarray(times, float)
    order = np.argsort(t, kind="stable")
    ts = t[order]
    sig, _ = _ready(plan, ts)
    rot = np.broadcast_to(plan.rot_ready, (len(t), 3, 3)).copy()
    for sp in plan.strokes:
        m = slice(np.searchsorted(ts, sp.t_start), np.searchsorted(ts, sp.t_end, side="right"))
        if m.start == m.stop:
            continue
        neutral, prepared, actual = np.split(sp.spline(ts[m]), 3, axis=1)
        w = smoothstep(ts[m], sp.intent_start, sp.t_hit)[:, None]
        w_late = smoothstep(ts[m], sp.late_start, sp.t_hit)[:, None]
        sig[m] = neutral + w * (prepared - neutral) + w_late * (actual - prepared)
        rot[m] = sp.rot_ref @ Rotation.from_rotvec(sig[m, ROT]).as_matrix()
    unsort = np.empty_like(order)
    unsort[order] = np.arange(len(t))
    sig, rot = sig[unsort], rot[unsort]
    return _pose(plan, t, sig, rot)


def _pose(plan: PlayerPlan, t: np.ndarray, sig: np.ndarray, rot: np.ndarray) -> StrokeTrajectory:
    style, dims, base = plan.style, plan.dims, plan.base
    h, k = style.handedness, style.height / 1.75
    twist, lean = sig[:, TWIST], sig[:, LEAN]
    trunk = base @ rot_z(twist) @ rot_x(-lean)
    neck = sig[:, ROOT] + trunk[:, :, 2] * dims.torso
    play, free = (0, 1) if h > 0 else (1, 0)
    wrists, hints = np.empty((len(t), 2, 3)), np.empty((len(t), 2, 3))
    wrists[:, play] = sig[:, POS] - dims.paddle_reach * rot[:, :, 0]
    # Elbow near where a forearm in line with the handle would put it, pulled down and outwards.
    hints[:, play] = (wrists[:, play] - dims.forearm * rot[:, :, 0]
                      + 0.35 * base @ np.array([h * 0.4, -0.3, -0.87]))
    wrists[:, free] = neck + trunk @ (np.array([-h * 0.12, 0.28, -0.32]) * k)
    hints[:, free] = neck + trunk @ np.array([-h * 0.4, -0.2, -0.5])
    joints = pose_joints(dims, base, sig[:, ROOT], twist, lean, wrists, hints, sig[:, ROOT],
                         style.stance_width, 0.12 * k * h)
    wrist = joints[:, J["RWrist"] if h > 0 else J["LWrist"]]
    return StrokeTrajectory(t, joints, wrist + dims.paddle_reach * rot[:, :, 0], rot,
                            tuple(sp.forehand for sp in plan.strokes))


def stroke(times: np.ndarray, side: int, t_hit: float, p_hit: np.ndarray, paddle_normal_hit: np.ndarray,
           paddle_velocity_hit: np.ndarray, target_x: float, style: PlayerStyle, rng: np.random.Generator,
           late_change: float | None = None) -> StrokeTrajectory:
    """One stroke from the ready position and back, sampled at times (s).

    p_hit is the paddle centre at impact (`paddle_centre_at_impact`). To sample the same stroke at
    several rates (joints at 100 Hz, paddle at 120 Hz), plan once with `plan_player` and call
    `evaluate_player` per rate.
    """
    hit = Hit(t_hit, np.asarray(p_hit, float), np.asarray(paddle_normal_hit, float),
              np.asarray(paddle_velocity_hit, float), target_x, late_change)
    # The player has seen the ball coming and moved towards it (as in a rally).
    plan = plan_player(side, [hit], style, rng, track_times=[t_hit - 1.0], track_x=[hit.paddle_pos[0]])
    return evaluate_player(plan, times)
