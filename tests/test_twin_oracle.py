"""The twin's shot repertoire and its oracle (pingpong.twin.repertoire, pingpong.twin.oracle).

On one simulated stretch of play (15 rallies): each stroke's speed and spin, the decisions held fixed
in the oracle's re-draws exactly when they were made before the frame, the oracle's flight against the
twin's own, its calibration (the true strike x inside [q05, q95] about 90 % of the time) and its
coverage of every good shot and frame.
"""

import numpy as np
import pandas as pd
import pytest

from pingpong.frames import N_PRED_FRAMES
from pingpong.twin.oracle import held, redraw_decisions, session_oracle, strike_x_batch
from pingpong.twin.repertoire import REV
from pingpong.twin.session import FaultRates, simulate_rallies


@pytest.fixture(scope="module")
def play():
    rec, _, _, _, records, _ = simulate_rallies(15, FaultRates(), np.random.default_rng(11))
    shots = pd.DataFrame(rec.shots)
    oracle = session_oracle(records, np.random.default_rng(12), 0)
    return shots, records, oracle


def _good(shots):
    ok = shots[shots.outcome == "ok"].copy()
    v = ok[["v_out_x", "v_out_y", "v_out_z"]].to_numpy()
    w = ok[["w_out_x", "w_out_y", "w_out_z"]].to_numpy()
    ok["speed"] = np.linalg.norm(v, axis=1)
    ok["spin_rev_s"] = np.linalg.norm(w, axis=1) / REV
    ok["backspin"] = np.cross(w, v)[:, 2] > 0
    return ok


def test_each_stroke_has_its_speed_and_spin(play):
    ok = _good(play[0])
    by = ok.groupby("stroke")
    assert set(by.groups) >= {"drive", "loop", "push", "block", "sidespin"}
    assert ok.loc[ok.stroke == "push", "backspin"].all()  # pushes carry backspin
    # nearly nothing else does (a paddle cannot always turn round a heavy incoming backspin)
    assert ok.loc[ok.stroke != "push", "backspin"].mean() < 0.05
    assert by.speed.median()["push"] < 6.5 < by.speed.median()["drive"]
    assert by.spin_rev_s.median()["block"] < 20 < by.spin_rev_s.median()["loop"]
    assert ok.spin_rev_s.median() >= 20  # the bar: tens of rev/s, as in human play


def test_held_decisions_never_vary_across_redraws(play):
    _, records, _ = play
    rng = np.random.default_rng(0)
    for record in records[:20]:
        for f in (0, 5, 10, 20, 30):
            hold_intent, hold_late = held(record, f)
            assert hold_intent == (record.timing.reveal_s > f * 0.01)
            intent, final, execution = redraw_decisions(record, hold_intent, hold_late, rng, 200)
            assert (intent["target"] == record.intent["target"]).all() == hold_intent
            if hold_late:  # made after the intent, so the intent is held too
                assert hold_intent and (final["target"] == record.final["target"]).all()
                assert (final["late"] == record.final["late"]).all()
            assert np.ptp(execution["target_error"][:, 0]) > 0  # the contact is never decided yet


def test_oracle_flight_reproduces_the_twins(play):
    shots, records, _ = play
    by_key = shots.set_index(["rally", "shot"])
    for record in records[:30]:
        row = by_key.loc[(record.rally, record.shot)]
        v = row[["v_out_x", "v_out_y", "v_out_z"]].to_numpy(float)[None]
        w = row[["w_out_x", "w_out_y", "w_out_z"]].to_numpy(float)[None]
        x = strike_x_batch(record.ctx.p_hit, v, w, record.execution["params"], record.ctx.side)
        assert x[0] == pytest.approx(row.strike_x, abs=0.005)


def test_oracle_covers_every_good_shot_and_frame(play):
    shots, records, oracle = play
    assert len(oracle) == len(records) * (N_PRED_FRAMES + 1)
    assert (shots.outcome == "ok").sum() == len(records)
    assert oracle.oracle_n.quantile(0.05) >= 100  # most draws are good shots, for nearly every shot
    assert (oracle.oracle_q05_x <= oracle.oracle_mean_x).all()
    assert (oracle.oracle_mean_x <= oracle.oracle_q95_x).all()


def test_oracle_is_calibrated_and_narrows_towards_the_hit(play):
    shots, _, oracle = play
    m = oracle.merge(shots[["rally", "shot", "strike_x"]], on=["rally", "shot"])
    inside = (m.strike_x >= m.oracle_q05_x) & (m.strike_x <= m.oracle_q95_x)
    coverage = inside.groupby(m.frames_before_hit).mean()
    # ~100 shots: a binomial 90 % has a standard deviation of 3 points
    assert coverage[0] == pytest.approx(0.9, abs=0.08) and coverage[20] == pytest.approx(0.9, abs=0.08)
    std = m.groupby("frames_before_hit").oracle_std_x.mean()
    assert std[0] < std[10] < std[30]
