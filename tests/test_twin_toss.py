"""The serve's toss of config twin.serve_toss (pingpong.twin.session): ballistic from the free palm, rising
>= 16 cm (ITTF Law 2.06.02), falling onto the serve's hit point with the serve's incoming velocity; the
server's free hand under the ball at the release; and off, the twin's tables bit for bit those without it.

One session of 4 rallies per switch (seed 11, another than the twin's other tests'), ~10 s each.
"""

import hashlib

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pingpong.common.seeding import rng_for
from pingpong.frames import BALL_RADIUS, GRAVITY, TABLE_HALF_LENGTH
from pingpong.twin import render
from pingpong.twin.ball import BallParams, simulate_flight
from pingpong.twin.players import HAND_BEYOND_WRIST, J
from pingpong.twin.session import (
    PALM_DEPTH_M,
    TOSS_SHOT,
    FaultRates,
    launch_speed,
    simulate_session,
    toss_flight,
)

SEED = 11
RALLIES = 4
MIN_RISE_M = 0.16  # Law 2.06.02: the ball rises at least 16 cm after leaving the palm


@pytest.fixture(scope="module")
def tossed():
    return simulate_session(RALLIES, FaultRates(), rng_for(SEED, "session"), serve_toss=True)


def _tosses(truth) -> dict[int, pd.DataFrame]:
    ball = truth.ball
    return {rally: rows for rally, rows in ball[ball["shot"] == TOSS_SHOT].groupby("rally")}


def test_every_serve_has_a_toss_that_rises_from_the_palm(tossed):
    tosses = _tosses(tossed)
    assert sorted(tosses) == list(range(RALLIES))
    for rows in tosses.values():
        z = rows["z"].to_numpy()
        assert z.max() - z[0] >= MIN_RISE_M - 1e-9
        assert z[0] > BALL_RADIUS  # released above the playing surface (Law 2.06.04)
        y = rows["y"].to_numpy()
        assert (np.abs(y) > TABLE_HALF_LENGTH).all()  # behind the end line throughout


def test_toss_is_ballistic(tossed):
    """Spinless, only gravity and drag: a(t) from the samples' velocities equals -g z - k_D |v| v to 1e-3
    m/s^2 (central differences of the 1 kHz RK4 samples), and the spin is zero."""
    k = BallParams().k_drag
    for rows in _tosses(tossed).values():
        t = (rows["time_ns"].to_numpy() - rows["time_ns"].iloc[0]) / 1e9
        v = rows[["vx", "vy", "vz"]].to_numpy()
        assert np.abs(rows[["wx", "wy", "wz"]].to_numpy()).max() == 0
        a = (v[2:] - v[:-2]) / (t[2:] - t[:-2])[:, None]
        vm = v[1:-1]
        expected = -k * np.linalg.norm(vm, axis=1, keepdims=True) * vm - np.array([0.0, 0.0, GRAVITY])
        np.testing.assert_allclose(a, expected, atol=1e-3)


def test_toss_ends_at_the_serve_with_its_incoming_velocity(tossed):
    """The toss's last sample is 1 ms or less before the serve's hit, within 1 ms of flight (3.5 mm at the
    fastest fall) of the hit point, its velocity the serve's v_in to 0.01 m/s (1 ms of gravity), falling."""
    shots = tossed.shots
    for rally, rows in _tosses(tossed).items():
        serve = shots[(shots["rally"] == rally) & (shots["shot"] == 0)].iloc[0]
        last = rows.iloc[-1]
        assert 0 <= serve["t_hit_ns"] - last["time_ns"] <= 1_000_000
        hit = serve[["hit_x", "hit_y", "hit_z"]].to_numpy(float)
        v_in = serve[["v_in_x", "v_in_y", "v_in_z"]].to_numpy(float)
        assert np.linalg.norm(last[["x", "y", "z"]].to_numpy(float) - hit) < 4e-3
        np.testing.assert_allclose(last[["vx", "vy", "vz"]].to_numpy(float), v_in, atol=0.011)
        assert v_in[2] < 0
        # the fall from the apex: vz^2 = 2 g h less the drag's share (<= 10 % at these speeds)
        fall = rows["z"].max() - hit[2]
        assert 0.9 * 2 * GRAVITY * fall <= v_in[2] ** 2 <= 2 * GRAVITY * fall + 1e-6


def test_pause_before_the_serve_still_separates_rallies(tossed):
    """The toss's time is added to the pause: each rally's first sample (the release) is >= 0.5 s after
    the previous rally's last, more than curation's 0.4 s rally gap."""
    spans = tossed.ball.groupby("rally")["time_ns"].agg(["min", "max"])
    gaps = (spans["min"].to_numpy()[1:] - spans["max"].to_numpy()[:-1]) / 1e9
    assert (gaps >= 0.5).all()


def test_free_hand_holds_the_ball_at_the_release(tossed):
    """At the people frame nearest each release the server's free hand (twin.render's disc) is under the
    ball within 1 cm, or, where the palm is beyond the arm, the arm is stretched straight towards it
    (shoulder-hand distance the two bones' sum to 0.1 %: players.two_link's nearest reachable point)."""
    people, shots = tossed.people, tossed.shots
    held = 0
    for rally, rows in _tosses(tossed).items():
        server = shots[(shots["rally"] == rally) & (shots["shot"] == 0)].iloc[0]["hitter"]
        body = people[people["person"] == server]
        row = body.iloc[np.argmin(np.abs(body["time_ns"].to_numpy() - rows["time_ns"].iloc[0]))]
        joint = {name: row[[f"j{J[name]:02d}_{a}" for a in "xyz"]].to_numpy(float) for name in J}
        palm = rows[["x", "y", "z"]].iloc[0].to_numpy(float) - [0.0, 0.0, PALM_DEPTH_M]
        arms = []
        for s_, e, w in (("LShoulder", "LElbow", "LWrist"), ("RShoulder", "RElbow", "RWrist")):
            hand = joint[w] + HAND_BEYOND_WRIST * (joint[w] - joint[e])
            bones = np.linalg.norm(joint[e] - joint[s_]) + np.linalg.norm(hand - joint[e])
            arms.append((np.linalg.norm(hand - palm), np.linalg.norm(hand - joint[s_]) / bones))
        gap, stretch = min(arms)
        held += gap < 0.01
        assert gap < 0.01 or stretch > 0.999, (rally, gap, stretch)
    assert held >= 1  # the hand is moved at all


def test_hand_constants_are_the_renderers():
    assert PALM_DEPTH_M == render.HAND_RADIUS


@settings(max_examples=25, deadline=None)
@given(rise=st.floats(0.16, 0.6))
def test_launch_speed_reaches_the_rise(rise):
    """launch_speed's closed form against the RK4 flight: the apex within 0.5 mm (the 1 ms step's)."""
    v0 = np.array([0.0, 0.0, launch_speed(rise, BallParams())])
    flight = simulate_flight(np.array([0.0, 2.0, 0.1]), v0, np.zeros(3), BallParams(), t_max=0.8)
    assert abs(flight.positions[:, 2].max() - 0.1 - rise) < 5e-4


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), x=st.floats(-0.4, 0.4), back=st.floats(0.05, 0.35),
       z=st.floats(0.15, 0.35), side=st.sampled_from([1, -1]))
def test_toss_flight_falls_onto_any_hit_point(seed, x, back, z, side):
    """For any drawn hit point the toss ends there (0.1 mm horizontally; in height 10 um: the stop is refined
    by a partial RK4 step, measured 0.9 um off), falling, after rising >= 16 cm."""
    p_hit = np.array([x, side * (TABLE_HALF_LENGTH + back), z])
    flight = toss_flight(np.random.default_rng(seed), p_hit, side, BallParams())
    assert np.abs(flight.positions[-1, :2] - p_hit[:2]).max() < 1e-4
    assert abs(flight.positions[-1, 2] - z) < 1e-5
    assert flight.velocities[-1, 2] < 0
    assert flight.positions[:, 2].max() - flight.positions[0, 2] >= MIN_RISE_M - 1e-9


# SHA-256 (first 16 hex digits) of each table's CSV, values rounded to 1e-9, of simulate_session(3,
# FaultRates(), rng_for(23, "session")) at f3b62e0, before serve_toss existed (the same function run in a
# worktree of that commit); rounded so that a last-bit difference of another CPU's maths does not count,
# while any other draw or sample would.
BEFORE_TOSS = {"ball": "06397ad62bfabf2b", "shots": "84b59d674388255b", "events": "ca10d0676ebce6df",
               "people": "e2f0dcd470941602", "paddles": "91ad11af7a3d5c8e"}


def test_off_leaves_the_twin_unchanged():
    """serve_toss off draws and records nothing more: at another seed (23) the tables are those of the code
    before the toss (BEFORE_TOSS), and the toss changes them (the switch is not dead)."""
    off = simulate_session(3, FaultRates(), rng_for(23, "session"), serve_toss=False)
    on = simulate_session(3, FaultRates(), rng_for(23, "session"), serve_toss=True)
    digest = {name: hashlib.sha256(getattr(off, name).round(9).to_csv().encode()).hexdigest()[:16]
              for name in BEFORE_TOSS}
    assert digest == BEFORE_TOSS
    assert (on.ball["shot"] == TOSS_SHOT).any() and not (off.ball["shot"] == TOSS_SHOT).any()
