"""The twin's oracle: how much of a shot's strike point could be known at each frame before the hit.

A shot's decisions are made at known times (`pingpong.twin.repertoire`): the stroke before any
predicted frame, the intent `reveal_s` and the late change `late_s` before the hit, the execution
at the contact. At frame f (f * 10 ms before the hit) the decisions made strictly before that time are
held and the others re-drawn `n_draws` times from the same distributions; each draw is aimed and flown
to the far strike line like the shot itself, and the distribution of the strike x is kept. Frames
between two decision times share one set of draws.

Conditioned on a good shot, as every kept hit is one: draws whose ball does not cross the net, bounce
once on the far half and reach the strike line are left out (`oracle_n` counts those kept).

Two approximations, both measured by tests/test_twin_oracle.py (the true strike x must fall within
[q05, q95] about 90 % of the time, and the oracle's flight must reproduce the shot's own):
- the spin flown is the wanted spin scaled by the ratio the shot's own paddle achieved (the twin
  solves a paddle per shot, `paddle_for_spin`; 200 solves per draw set would cost minutes);
- the flight integrates at 4 ms with the bounce placed by linear interpolation in its step
  (simulate_flight: 1 ms with the event refined), within 5 mm at the strike line (tested).
"""

import numpy as np
import pandas as pd

from pingpong.frames import FRAME_NS, N_PRED_FRAMES, STRIKE_Y, TABLE_HALF_LENGTH, TABLE_HALF_WIDTH
from pingpong.twin.ball import SLOWER_AIMS, BallParams, _contact, aim_shots, rk4_rows
from pingpong.twin.repertoire import draw_execution, draw_intent, draw_late, executed_shot

N_DRAWS = 200
BATCH_DRAWS = 20_000  # balls flown at once: numpy's per-call overhead amortised, a few MB an array
ORACLE_COLUMNS = ("rally", "shot", "t_hit_ns", "frames_before_hit", "oracle_mean_x", "oracle_std_x",
                  "oracle_q05_x", "oracle_q95_x", "oracle_n")
_FRAME_S = FRAME_NS / 1e9


def held(record, frames_before_hit: int) -> tuple[bool, bool]:
    """(intent held, late change held) at a frame: made strictly before f * 10 ms before the hit."""
    before = frames_before_hit * _FRAME_S
    return record.timing.reveal_s > before, record.timing.late_s > before


def _tile(draw: dict, n: int) -> dict:
    return {k: np.repeat(v, n, axis=0) for k, v in draw.items() if isinstance(v, np.ndarray)}


def redraw_decisions(record, hold_intent: bool, hold_late: bool, rng: np.random.Generator, n: int,
                     ball: BallParams = BallParams()) -> tuple[dict, dict, dict]:
    """n draws of a shot's intent, late change and execution, the held ones the shot's own; the
    execution (at the contact) is always re-drawn."""
    tac, timing, ctx = record.tactics, record.timing, record.ctx
    intent = _tile(record.intent, n) if hold_intent else draw_intent(rng, tac, timing, ctx, n)
    final = _tile(record.final, n) if hold_late else draw_late(rng, tac, timing, ctx, intent)
    return intent, final, draw_execution(rng, tac, timing, ctx, n, ball)


def redraw(record, hold_intent: bool, hold_late: bool, rng: np.random.Generator, n: int,
           ball: BallParams = BallParams()):
    """n re-drawn shots (redraw_decisions): targets (n, 2), speed hints (n,), wanted spins (n, 3), params,
    net heights (n,) m."""
    intent, final, execution = redraw_decisions(record, hold_intent, hold_late, rng, n, ball)
    target, speed, w, net_height = executed_shot(record.ctx, record.timing, intent, final, execution)
    return target, speed, w, execution["params"], net_height


def paddle_spin(w_wanted, v_out, v_in, w_in, ratio) -> np.ndarray:
    """The spin (n, 3) a brushing paddle gives, approximated: friction acts in the face, so the wanted
    spin across the face normal is given (scaled by the ratio (n, 1) the shot's own paddle achieved) and
    the incoming spin w_in (n, 3) about the normal stays. The normal is taken along v_out - v_in (the
    frictionless paddle's, paddle_for_outgoing's start)."""
    n = v_out - v_in
    n /= np.linalg.norm(n, axis=1, keepdims=True)

    def along(w):
        return np.sum(w * n, axis=1, keepdims=True) * n

    return ratio * (w_wanted - along(w_wanted)) + along(w_in)


def _aim(p_hit, target, w, params, speed, net_height, flight_time=None):
    """Outgoing velocities (n, 3) from p_hit (n, 3), NaN where no speed hint clears the net at net_height
    (n,) m over its top edge (the twin's _aim_slower), and their flight times (n,); a given flight_time (n,)
    starts the aim from there instead."""
    margin = net_height - np.array([q.radius for q in params])
    v, T = np.full((len(target), 3), np.nan), np.full(len(target), np.nan)
    for factor in SLOWER_AIMS:
        todo = np.flatnonzero(np.isnan(v[:, 0]))
        if len(todo) == 0:
            break
        start = None if flight_time is None else flight_time[todo]
        v[todo], T[todo] = aim_shots(p_hit[todo], target[todo], w[todo],
                                     [params[i] for i in todo], flight_time=start,
                                     speed_hint=speed[todo] * factor, net_margin=margin[todo], strict=False)
        flight_time = None  # what the given times could not clear falls back to the speed hints
    return v, T


def strike_x_batch(p_hit, v_out, w, params, side, dt: float = 0.004, t_max: float = 2.5) -> np.ndarray:
    """x (n,) where each ball, hit at p_hit ((3,) or (n, 3)) by the player at side (+1/-1, or (n,)),
    crosses the far strike line y = side * STRIKE_Y after exactly one bounce on the far half; NaN for
    balls that do not (no bounce there, a second bounce, the floor)."""
    n = len(v_out)
    kd, km, ks = (np.array([getattr(q, a) for q in params])
                  for a in ("k_drag", "k_magnus", "magnus_saturation"))
    e = np.array([q.table_restitution for q in params])[:, None]
    mu = np.array([q.table_friction for q in params])[:, None]
    r = params[0].radius
    p, v, w = np.broadcast_to(p_hit, (n, 3)).T.copy(), v_out.T.copy(), w.T.copy()
    side = np.broadcast_to(side, (n,))
    bounced, active = np.zeros(n, bool), np.isfinite(v[0])
    x = np.full(n, np.nan)
    live = np.arange(n)  # the balls still flown: every step is per ball, so dropping the others moves no bit
    for _ in range(int(t_max / dt)):
        p1, v1 = rk4_rows(p, v, w, kd, km, ks, dt)
        down = active & (p[2] > r) & (p1[2] <= r)
        if down.any():
            f = (p[2] - r) / (p[2] - p1[2])
            at = p + f * (p1 - p)
            y_own = side * at[1]  # the hitter's own frame: the far half is -1.37 <= y_own < 0
            on_far = (down & (np.abs(at[0]) <= TABLE_HALF_WIDTH) & (y_own < 0)
                      & (y_own >= -TABLE_HALF_LENGTH))
            active &= ~(down & (bounced | ~on_far))  # a second bounce, or one off the far half
            hit = on_far & active
            if hit.any():
                vb, wb = _contact((v + f * (v1 - v))[:, hit].T, w[:, hit].T, np.array([0.0, 0.0, 1.0]),
                                  e[hit], mu[hit], r)
                p1[:, hit], v1[:, hit], w[:, hit] = at[:, hit], vb.T, wb.T
                p1[2, hit] = r
                bounced |= hit
        y0, y1 = side * p[1], side * p1[1]
        cross = active & (y0 > STRIKE_Y) & (y1 <= STRIKE_Y)
        if cross.any():
            done = cross & bounced
            f = (y0[done] - STRIKE_Y) / (y0[done] - y1[done])
            x[live[done]] = p[0, done] + f * (p1[0, done] - p[0, done])
        active &= ~cross & (p1[2] > -0.76)
        p, v = p1, v1
        n_active = np.count_nonzero(active)
        if n_active == 0:
            break
        if n_active < 0.75 * len(live):  # most balls are done: fly the others alone
            keep = np.flatnonzero(active)
            p, v, w = p[:, keep], v[:, keep], w[:, keep]
            kd, km, ks, e, mu = kd[keep], km[keep], ks[keep], e[keep], mu[keep]
            side, bounced, active, live = side[keep], bounced[keep], active[keep], live[keep]
    return x


def oracle_flights(shots: dict, target, speed, w_wanted, params, net_height) -> np.ndarray:
    """Strike x (n,) of n shots aimed like the twin's: aimed with the wanted spin, the paddle's spin
    (paddle_spin) estimated from that aim, re-aimed with it and flown (NaN: not a good shot). shots: each
    draw's hit, {"p_hit", "v_in", "w_in": (n, 3), "side", "spin_ratio": (n,)}."""
    ratio = shots["spin_ratio"][:, None]
    w = w_wanted * ratio
    v, T = _aim(shots["p_hit"], target, w, params, speed, net_height)
    ok = np.isfinite(v[:, 0])
    w[ok] = paddle_spin(w_wanted[ok], v[ok], shots["v_in"][ok], shots["w_in"][ok], ratio[ok])
    v, _ = _aim(shots["p_hit"], target, w, params, speed, net_height, np.where(ok, T, np.nan))
    return strike_x_batch(shots["p_hit"], v, w, params, shots["side"])


def _draw_sets(records, rng: np.random.Generator, n_draws: int, ball: BallParams) -> list:
    """(record index, held key, redraw's draws) for every shot's distinct held decisions, in frame order:
    frames between two decision times share one set."""
    return [(i, key, redraw(rec, *key, rng, n_draws, ball)) for i, rec in enumerate(records)
            for key in dict.fromkeys(held(rec, f) for f in range(N_PRED_FRAMES + 1))]


def _fly_sets(records, sets: list, n_draws: int, batch_draws: int) -> list[np.ndarray]:
    """The good draws' strike x of each draw set (n_draws balls each), flown batch_draws // n_draws sets at
    a time."""
    if not sets:
        return []
    hits = {"p_hit": np.stack([rec.ctx.p_hit for rec in records]),
            "v_in": np.stack([rec.ctx.v_in for rec in records]),
            "w_in": np.stack([rec.ctx.w_in for rec in records]),
            "side": np.array([rec.ctx.side for rec in records], float),
            "spin_ratio": np.array([rec.spin_ratio for rec in records])}
    per_batch, out = max(1, batch_draws // n_draws), []
    for first in range(0, len(sets), per_batch):
        batch = sets[first:first + per_batch]
        owner = np.repeat([i for i, _, _ in batch], n_draws)
        target, speed, w_wanted = (np.concatenate([draws[k] for _, _, draws in batch]) for k in range(3))
        params = [q for _, _, draws in batch for q in draws[3]]
        net_height = np.concatenate([draws[4] for _, _, draws in batch])
        xs = oracle_flights({k: v[owner] for k, v in hits.items()}, target, speed, w_wanted, params,
                            net_height)
        out += [x[np.isfinite(x)] for x in xs.reshape(len(batch), n_draws)]
    return out


def _summary(xs: np.ndarray) -> dict:
    q05, q95 = np.quantile(xs, [0.05, 0.95]) if len(xs) else (np.nan, np.nan)
    return {"oracle_mean_x": float(np.mean(xs)) if len(xs) else np.nan,
            "oracle_std_x": float(np.std(xs, ddof=1)) if len(xs) > 1 else np.nan,
            "oracle_q05_x": float(q05), "oracle_q95_x": float(q95), "oracle_n": len(xs)}


def session_oracle(records, rng: np.random.Generator, epoch_ns: int, n_draws: int = N_DRAWS,
                   ball: BallParams = BallParams(), batch_draws: int = BATCH_DRAWS) -> pd.DataFrame:
    """The oracle table of a session's good shots (ShotRecord), t_hit_ns on the session's clock.

    Every shot's draws are made first (the rng's order is the shots' and frames'), then flown together:
    batches of thousands of balls spend their time in arithmetic, not in numpy's per-call overhead
    (benchmarks/bench_oracle.py). batch_draws changes only the float rounding of the aim, not the draws:
    now and then a draw on the edge of clearing the net falls the other side (0-2 of 6,200 in the benchmark).
    """
    sets = _draw_sets(records, rng, n_draws, ball)
    flown = _fly_sets(records, sets, n_draws, batch_draws)
    summaries = {(i, key): _summary(xs) for (i, key, _), xs in zip(sets, flown, strict=True)}
    rows = [{"rally": rec.rally, "shot": rec.shot, "t_hit_ns": int(round(rec.t_hit * 1e9)) + epoch_ns,
             "frames_before_hit": f, **summaries[i, held(rec, f)]}
            for i, rec in enumerate(records) for f in range(N_PRED_FRAMES + 1)]
    out = pd.DataFrame(rows, columns=list(ORACLE_COLUMNS))
    return out.astype({"rally": np.int32, "shot": np.int32, "t_hit_ns": np.int64,
                       "frames_before_hit": np.int32, "oracle_n": np.int32})
