"""Ball events from a 3D ball track: table bounces, paddle hits and net crossings (detect_events, which
the filtering rule runs on the raw ball), and the unconfirmed samples dropped before.

All detectors work on the finite samples only (a NaN row is a frame the ball was not seen), so NaN
gaps neither create nor hide events; a turn inside a gap of up to MAX_HIDDEN_FRAMES unseen frames is found
at the sample beside it, its slopes and meeting time fitted from beyond the gap (a bounce so hidden may
still be lost: the samples beside it can lie above the height tolerance). Velocities are slopes of
straight-line fits over `span` s either side of a sample, not sample differences, so that 3 mm of
triangulation noise (0.4 m/s on a 10 ms difference) cannot fake a turn.
"""

import numpy as np
import pandas as pd

from pingpong.curation.schemas import EVENT_COLUMNS
from pingpong.curation.tracks import PLAYER_END, fill_short_gaps, frame_seconds, paddle_arrays
from pingpong.frames import BALL_RADIUS, GRAVITY, TABLE_HALF_LENGTH, TABLE_HALF_WIDTH

TABLE_EXTENT = (-TABLE_HALF_WIDTH, TABLE_HALF_WIDTH, -TABLE_HALF_LENGTH, TABLE_HALF_LENGTH)  # x, x, y, y
MAX_HIDDEN_FRAMES = 3  # the longest gap a turn is looked for in: the ball behind the paddle at contact


def _finite(times, ball):
    times, ball = np.asarray(times, float), np.asarray(ball, float)
    if ball.ndim != 2 or ball.shape[1] != 3 or len(times) != len(ball):
        raise ValueError(f"need times (T,) and ball (T, 3), got {times.shape} and {ball.shape}")
    index = np.flatnonzero(np.isfinite(ball).all(axis=1) & np.isfinite(times))
    return index, times[index], ball[index]


def _sampling_step(t: np.ndarray) -> float:
    """The track's usual sampling interval (s): the median step between its finite samples."""
    return float(np.median(np.diff(t))) if len(t) >= 2 else np.inf


def _slope(t: np.ndarray, v: np.ndarray) -> float:
    """Least-squares slope of v(t); NaN with fewer than 2 samples."""
    return float(np.polyfit(t, v, 1)[0]) if len(t) >= 2 else np.nan


def _across_gaps(t: np.ndarray, i: int, step: float) -> tuple[int, int]:
    """(first, last): sample i's neighbours before and after where 1 to MAX_HIDDEN_FRAMES samples (of
    `step` s) are missing between them and i, else i.

    A turn can lie in a short gap (the ball hidden behind the paddle at contact): a fit from sample i across
    the gap would straddle it, so the fits on that side start at the first sample beyond the gap instead.
    Not across longer gaps: after the last sample of a ball falling to the floor, the next one seen is the
    next rally's (measured: 12 spurious bounces in the default run's four sessions when any gap was crossed).
    """
    def short_gap(dt):
        return 1.5 * step < dt < (MAX_HIDDEN_FRAMES + 1.5) * step

    first = i - 1 if i > 0 and short_gap(t[i] - t[i - 1]) else i
    last = i + 1 if i + 1 < len(t) and short_gap(t[i + 1] - t[i]) else i
    return first, last


def _turns(t: np.ndarray, v: np.ndarray, i: int, span: float, step: float) -> tuple[float, float]:
    """Slopes of v over span s up to sample i and from it (i in both), each side from beyond a gap next to
    i without i (_across_gaps: measured, a hit hidden for 2 frames had an after-slope of 0.33 m/s)."""
    first, last = _across_gaps(t, i, step)
    lo, hi = np.searchsorted(t, t[first] - span), np.searchsorted(t, t[last] + span, side="right")
    return _slope(t[lo:first + 1], v[lo:first + 1]), _slope(t[last:hi], v[last:hi])


def _window_extreme(t: np.ndarray, v: np.ndarray, i: int, span: float, sign: float) -> bool:
    """Whether v[i] is the first minimum (sign +1) or maximum (sign -1) of v over t_i +- span."""
    lo, hi = np.searchsorted(t, t[i] - span), np.searchsorted(t, t[i] + span, side="right")
    return lo + int(np.argmin(sign * v[lo:hi])) == i


def _meeting_time(t: np.ndarray, v: np.ndarray, i: int, window: float, curvature: float,
                  step: float) -> float:
    """Time where curves fitted to v before and after sample i meet, i excluded from both fits, each over
    window s from i's neighbour on its side (_across_gaps: beyond a gap next to i, else i).

    Both curves are v = curvature/2 (t - t_i)^2 + a + b (t - t_i) with the curvature given (gravity for a
    bounce's z, 0 for a hit's y): fitting it on ~8 noisy samples moves the meeting point by frames.
    Then the difference of the two curves is linear, so they meet once. Returns t_i when a side has
    fewer than 2 samples or the meeting point is more than one sampling interval away.
    """
    first, last = _across_gaps(t, i, step)
    s = t - t[i]
    u = v - 0.5 * curvature * s**2
    before = (t >= t[first] - window) & (s < 0)
    after = (s > 0) & (t <= t[last] + window)
    if before.sum() < 2 or after.sum() < 2:
        return float(t[i])
    b_pre, a_pre = np.polyfit(s[before], u[before], 1)
    b_post, a_post = np.polyfit(s[after], u[after], 1)
    meet = (a_post - a_pre) / (b_pre - b_post)
    reach = max(-s[before].max(), s[after].min())
    return float(t[i] + meet) if abs(meet) <= reach else float(t[i])


def _over_table(xy: np.ndarray, extent) -> bool:
    return extent is None or (extent[0] <= xy[0] <= extent[1] and extent[2] <= xy[1] <= extent[3])


def detect_bounces(times, ball, table_z: float = 0.0, radius: float = BALL_RADIUS, height_tol: float = 0.05,
                   table_extent=TABLE_EXTENT, span: float = 0.03, min_speed: float = 0.3,
                   fit_window: float = 0.08, subframe: bool = True) -> pd.DataFrame:
    """Table bounces of a ball track (T, 3): DataFrame(index, time, x, y, z, side), one row per bounce.

    A bounce is a sample whose ball-centre height above the contact height (table_z + radius) is the
    lowest within +-span s, at most height_tol m (the frame nearest the contact can be ~|v_z| / 200 Hz
    above it), with z's slope over span s before below -min_speed and after above +min_speed (m/s), its
    contact over table_extent (x_min, x_max, y_min, y_max; None skips the check). index: that sample;
    time: the
    contact, where gravity parabolas fitted to z over fit_window s either side meet (sample time if
    subframe is False); x, y, z: the ball centre there; side: '+y' or '-y', the table half by y's sign.
    """
    index, t, p = _finite(times, ball)
    step = _sampling_step(t)
    h = p[:, 2] - table_z - radius
    rows = []
    for i in range(1, len(t) - 1):
        if h[i] > height_tol or h[i] > h[i - 1] or h[i] > h[i + 1]:
            continue
        if not _window_extreme(t, h, i, span, 1.0):
            continue
        down, up = _turns(t, h, i, span, step)
        if not (down <= -min_speed and up >= min_speed):
            continue
        t_contact = _meeting_time(t, p[:, 2], i, fit_window, -GRAVITY, step) if subframe else float(t[i])
        x, y = (float(np.interp(t_contact, t, p[:, k])) for k in (0, 1))
        if not _over_table((x, y), table_extent):  # the contact, not the nearest frame (5 cm off at 5 m/s)
            continue
        z = _contact_height(t, p[:, 2], i, t_contact, fit_window)
        rows.append({"index": int(index[i]), "time": t_contact, "x": x, "y": y, "z": z,
                     "side": "+y" if y >= 0 else "-y"})
    return pd.DataFrame(rows, columns=["index", "time", "x", "y", "z", "side"])


def _contact_height(t, z, i, t_contact, window) -> float:
    """z at t_contact from the gravity parabola fitted to the samples before sample i (or after, when the
    contact lies after it); the sample's own z where that side has fewer than 2 samples."""
    s = t - t[i]
    side = (s >= -window) & (s < 0) if t_contact <= t[i] else (s > 0) & (s <= window)
    if side.sum() < 2:
        return float(z[i])
    u = z[side] + 0.5 * GRAVITY * s[side] ** 2
    b, a = np.polyfit(s[side], u, 1)
    dt = t_contact - t[i]
    return float(a + b * dt - 0.5 * GRAVITY * dt**2)


def detect_hits(times, ball, paddle_pos: dict, max_distance: float = 0.3, span: float = 0.03,
                min_speed: float = 0.5, table_z: float = 0.0, radius: float = BALL_RADIUS,
                min_height: float = 0.05, table_extent=TABLE_EXTENT) -> pd.DataFrame:
    """Paddle hits of a ball track (T, 3): DataFrame(index, time, player, x, y, z), one row per hit.

    paddle_pos maps each player to their paddle centre (T, 3) on the same frames (NaN where not tracked).
    A hit is a sample where y is extreme within +-span s, y's slope over span s before and after has
    opposite signs, both at least min_speed (m/s), the nearest paddle is within max_distance (m), and
    the ball is not on the table (over table_extent, less than min_height above the contact height;
    heavy backspin can turn a ball back there). index: that sample; time: where straight lines fitted to
    y over span s either side meet; player: the nearest paddle's; x, y, z: the ball at the sample.
    """
    index, t, p = _finite(times, ball)
    step = _sampling_step(t)
    paddles = {name: np.asarray(pos, float)[index] for name, pos in paddle_pos.items()}
    y = p[:, 1]
    rows = []
    for i in range(1, len(t) - 1):
        sign = 1.0 if y[i] <= min(y[i - 1], y[i + 1]) else -1.0 if y[i] >= max(y[i - 1], y[i + 1]) else 0.0
        if sign == 0.0 or not _window_extreme(t, y, i, span, sign):
            continue
        before, after = _turns(t, y, i, span, step)
        if not (sign * before <= -min_speed and sign * after >= min_speed):
            continue
        on_table = p[i, 2] - table_z - radius < min_height and _over_table(p[i, :2], table_extent)
        distance = {name: np.linalg.norm(pos[i] - p[i]) for name, pos in paddles.items()}
        distance = {name: d for name, d in distance.items() if np.isfinite(d)}
        if on_table or not distance:
            continue
        player = min(distance, key=distance.get)
        if distance[player] > max_distance:
            continue
        t_hit = _meeting_time(t, y, i, span, 0.0, step)
        rows.append({"index": int(index[i]), "time": t_hit, "player": player,
                     "x": float(p[i, 0]), "y": float(p[i, 1]), "z": float(p[i, 2])})
    return pd.DataFrame(rows, columns=["index", "time", "player", "x", "y", "z"])


def detect_net_crossings(times, ball, net_y: float = 0.0, hysteresis: float = 0.02) -> pd.DataFrame:
    """Crossings of the net plane y = net_y: DataFrame(index, time, direction).

    The ball's side only changes once it is more than `hysteresis` m beyond the plane, so noise around
    the plane gives one crossing. index: the first sample past the plane; time: linear interpolation of
    y between it and the sample before (across a NaN gap too); direction: '+y' or '-y', where it goes.
    """
    index, t, p = _finite(times, ball)
    d = p[:, 1] - net_y
    rows = []
    side = 0.0
    last_on_side = -1  # last sample strictly on the current side
    for k in range(len(d)):
        if side != 0.0 and d[k] * side > 0:
            last_on_side = k
        if abs(d[k]) > hysteresis and np.sign(d[k]) != side:
            if side != 0.0:
                j = last_on_side + 1  # first sample at or past the plane
                f = d[j - 1] / (d[j - 1] - d[j])
                rows.append({"index": int(index[j]), "time": float(t[j - 1] + f * (t[j] - t[j - 1])),
                             "direction": "+y" if side < 0 else "-y"})
            side, last_on_side = float(np.sign(d[k])), k
    return pd.DataFrame(rows, columns=["index", "time", "direction"])


def drop_ball_outliers(ball3d: pd.DataFrame, max_speed: float = 40.0, margin: float = 0.05,
                       neighbours: int = 2, fs_hz: float = 100.0, causal: bool = False) -> pd.DataFrame:
    """ball3d with the samples no neighbour confirms set unseen (x, y, z NaN, n_views 0): a sample is
    kept when a seen sample within `neighbours` frames lies within max_speed (m/s, above a smash) * dt
    + margin (m) of it, and no seen sample between the two agrees (within its own gate) with the
    neighbour but not with it. A triangulation onto a wrong pair of detections lands metres off its
    flight; an isolated sample cannot be checked and is dropped too. The between-rule: a neighbour two
    frames away may sit within the two-frame gate (0.85 m) of an outlier 0.77 m off its flight, while the
    sample between them, on the flight, says which of the two is off (a twin session put such an outlier
    at the net, where it made two spurious net crossings that cut the filter).

    causal: only the `neighbours` frames before a sample confirm it (rows in time order), so the decision
    on a frame never waits for later ones, as live. Its cost: the first sample after a gap of more than
    `neighbours` frames (and the session's first) has nothing to confirm it and is dropped as well."""
    xyz = ball3d[["x", "y", "z"]].to_numpy(float)
    n = len(xyz)
    # agree[k][a]: samples a and a + k are within the k-frame gate (NaN: False)
    agree = {k: np.linalg.norm(xyz[k:] - xyz[:-k], axis=1) <= max_speed * k / fs_hz + margin
             for k in range(1, neighbours + 1)}
    confirmed = np.zeros(n, bool)
    for k, pair in agree.items():
        confirms_later, confirms_earlier = pair.copy(), pair.copy()
        for m in range(1, k):  # the sample a + m between a and a + k
            with_earlier, with_later = agree[m][:n - k], agree[k - m][m:n - k + m]
            confirms_later &= ~(with_earlier & ~with_later)
            confirms_earlier &= ~(with_later & ~with_earlier)
        confirmed[k:] |= confirms_later
        if not causal:
            confirmed[:-k] |= confirms_earlier
    out = ball3d.copy()
    dropped = ~confirmed & np.isfinite(xyz).all(axis=1)
    out.loc[dropped, ["x", "y", "z"]] = np.nan
    out.loc[dropped, "n_views"] = 0
    return out


def detect_events(ball3d: pd.DataFrame, paddle: pd.DataFrame, hit_max_distance: float = 0.3,
                  paddle_fill_s: float = 0.25, fs_hz: float = 100.0) -> pd.DataFrame:
    """Hits, table bounces and net crossings of a session's raw 3D ball (EVENTS columns, in time order).

    kind: 'hit' (player: the nearest paddle's; side: that player's end), 'bounce' (side: the table half)
    or 'net' (side: the direction the ball goes). index: the ball3d row; time_ns: the sub-frame event
    time. Paddle positions are interpolated across OptiTrack gaps of up to paddle_fill_s for this only:
    a paddle lost for a few frames around the contact must not lose the hit.
    """
    time_ns = ball3d["time_ns"].to_numpy(np.int64)
    t = frame_seconds(time_ns)
    ball = ball3d[["x", "y", "z"]].to_numpy(float)
    fill = int(round(paddle_fill_s * fs_hz))
    paddles = {p: fill_short_gaps(paddle_arrays(paddle, p, time_ns)[:, :3], fill) for p in PLAYER_END}
    # span: 3 samples either side at 100 Hz; at 0.03 s rounding in t can leave the third one out, and a
    # contact frame lost behind the paddle then leaves one side a single sample, too few to time the hit
    hits = detect_hits(t, ball, paddles, max_distance=hit_max_distance, span=3.5 / fs_hz)
    hits = hits.assign(kind="hit", side=hits["player"].map(PLAYER_END))
    bounces = detect_bounces(t, ball).assign(kind="bounce", player="")
    net = detect_net_crossings(t, ball)
    net = net.assign(kind="net", player="", side=net["direction"],
                     **{a: ball[net["index"].to_numpy(int), k] for k, a in enumerate("xyz")})
    found = [e for e in (hits, bounces, net) if len(e)]
    if not found:
        return pd.DataFrame({"kind": pd.Series(dtype=str), "index": pd.Series(dtype=np.int64),
                             "time_ns": pd.Series(dtype=np.int64), "player": pd.Series(dtype=str),
                             "side": pd.Series(dtype=str), **{a: pd.Series(dtype=float) for a in "xyz"}})
    events = pd.concat(found, ignore_index=True)
    events["time_ns"] = time_ns[0] + np.round(events["time"].to_numpy() * 1e9).astype(np.int64)
    events["index"] = events["index"].astype(np.int64)
    return events.sort_values(["index", "time_ns"], kind="stable").reset_index(drop=True)[list(EVENT_COLUMNS)]
