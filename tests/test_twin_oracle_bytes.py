"""The oracle's flights with finished balls dropped give the bits of flying every ball to the end.

strike_x_batch flies only the balls still in flight once most are done; every step is per ball, so the
strike x must not move a bit. The reference is the earlier loop (oracle.py at 5ae9637), verbatim in its
arithmetic; benchmarks/bench_oracle.py --before REV checks whole sessions' tables.
"""

import numpy as np

from pingpong.frames import STRIKE_Y, TABLE_HALF_LENGTH, TABLE_HALF_WIDTH
from pingpong.twin import oracle
from pingpong.twin.ball import _contact, rk4_rows
from pingpong.twin.session import FaultRates, simulate_rallies


def reference_strike_x(p_hit, v_out, w, params, side, dt=0.004, t_max=2.5):
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
    for _ in range(int(t_max / dt)):
        p1, v1 = rk4_rows(p, v, w, kd, km, ks, dt)
        down = active & (p[2] > r) & (p1[2] <= r)
        if down.any():
            f = (p[2] - r) / (p[2] - p1[2])
            at = p + f * (p1 - p)
            y_own = side * at[1]
            on_far = down & (np.abs(at[0]) <= TABLE_HALF_WIDTH) & (y_own < 0) & (y_own >= -TABLE_HALF_LENGTH)
            active &= ~(down & (bounced | ~on_far))
            hit = on_far & active
            if hit.any():
                vb, wb = _contact((v + f * (v1 - v))[:, hit].T, w[:, hit].T, np.array([0.0, 0.0, 1.0]),
                                  e[hit], mu[hit], r)
                p1[:, hit], v1[:, hit], w[:, hit] = at[:, hit], vb.T, wb.T
                p1[2, hit] = r
                bounced |= hit
        y0, y1 = side * p[1], side * p1[1]
        cross = active & (y0 > STRIKE_Y) & (y1 <= STRIKE_Y)
        f = (y0 - STRIKE_Y) / np.where(cross, y0 - y1, 1.0)
        x = np.where(cross & bounced, p[0] + f * (p1[0] - p[0]), x)
        active &= ~cross & (p1[2] > -0.76)
        p, v = p1, v1
        if not active.any():
            break
    return x


def test_strike_x_equals_flying_every_ball_to_the_end():
    records = simulate_rallies(3, FaultRates(), np.random.default_rng(5))[4]
    rng = np.random.default_rng(6)
    p_hit, v, w, params, side = [], [], [], [], []
    for rec in records[:8]:  # both players' shots: sides +1 and -1 in one batch
        target, speed, w_wanted, draw_params, net_height = oracle.redraw(rec, False, False, rng, 100)
        hits = np.repeat(rec.ctx.p_hit[None], 100, axis=0)
        aimed, _ = oracle._aim(hits, target, w_wanted, draw_params, speed, net_height)
        aimed[::7] *= rng.uniform(0.6, 1.4, (len(aimed[::7]), 1))  # long, short and netted balls too
        p_hit.append(hits), v.append(aimed), w.append(w_wanted), params.extend(draw_params)
        side.append(np.full(100, float(rec.ctx.side)))
    args = np.concatenate(p_hit), np.concatenate(v), np.concatenate(w), params, np.concatenate(side)
    new, old = oracle.strike_x_batch(*args), reference_strike_x(*args)
    assert np.isfinite(old).sum() > 200 and np.isnan(old).sum() > 20  # good and failed balls both
    assert new.tobytes() == old.tobytes()
