"""Shots at real heights (issue 41): the repertoire's strokes cross the net at their cited heights, the
default run's good shots spread over the net like human play, and the report measures it."""

import numpy as np
import pandas as pd
import pytest

from pingpong.common.seeding import rng_for
from pingpong.frames import NET_HEIGHT
from pingpong.reports.published_shots import NOT_FOUND
from pingpong.reports.twin_flights import HIGH_OVER_NET, net_crossings, net_table
from pingpong.reports.twin_shots import STATISTICS
from pingpong.twin.ball import BallParams, simulate_flight
from pingpong.twin.repertoire import STROKES, ShotContext, ShotTiming, Tactics, draw_intent, spin_vector
from pingpong.twin.session import FaultRates, _aim, simulate_rallies

DEFAULT_SEED = 20261121  # config/config.yaml
HODGES_FISH = (0.30, 0.91)  # m over the net: "one to three feet high" (Hodges 2019, repertoire's doc)
CAMERA_TOP = 1.8  # m over the table: about the top of the twin rig's views at the net (twin.rig)


def _flown(stroke: str, n: int = 12, seed: int = 3):
    """n shots of one stroke, aimed as the twin aims them from a typical hitting point against a topspin
    ball: (net-crossing heights over the tape (n,), speeds there (n,), apex z (n,), aimed heights (n,))."""
    rng = rng_for(seed, stroke)
    ctx = ShotContext(np.array([0.1, 1.6, 0.25]), np.array([0.0, 8.0, -1.0]), np.array([0.0, 0.0, 0.0]),
                      1, serve=False)
    tactics = Tactics(np.ones(len(STROKES)) / len(STROKES), np.array([0.2, 0.4, 0.4]), "neutral", 0.03, 0.03)
    intent = draw_intent(rng, tactics, ShotTiming(stroke, 0.3, 0.1), ctx, n)
    w = spin_vector(intent["target"], ctx.p_hit, intent["spin"], intent["tilt"], STROKES[stroke].backspin)
    heights, speeds, apex = [], [], []
    for k in range(n):
        v, w_out, _, _ = _aim(ctx.p_hit, ctx.v_in, ctx.w_in, intent["target"][k], w[k], intent["speed"][k],
                              BallParams(), "ok", float(intent["net_height"][k]))
        flight = simulate_flight(ctx.p_hit, v, w_out, t_max=3.0)
        y = flight.positions[:, 1]
        i = int(np.flatnonzero((y[:-1] > 0) & (y[1:] <= 0))[0])
        f = y[i] / (y[i] - y[i + 1])
        heights.append(flight.positions[i, 2] + f * (flight.positions[i + 1, 2] - flight.positions[i, 2])
                       - NET_HEIGHT)
        speeds.append(np.linalg.norm(flight.velocities[i]))
        apex.append(flight.positions[:, 2].max())
        assert flight.events[0].kind == "bounce" and flight.events[0].position[1] < 0  # lands on the far half
    return np.array(heights), np.array(speeds), np.array(apex), intent["net_height"]


@pytest.mark.parametrize("stroke", list(STROKES))
def test_every_stroke_crosses_at_least_its_aimed_height(stroke):
    heights, _, _, aimed = _flown(stroke, n=6)
    assert np.all(heights >= aimed - 0.005)  # the aim's margin holds to the rounding of its solve
    assert np.all(heights <= np.maximum(1.35 * aimed, aimed + 0.06))  # raised in 10 % steps of flight time


def test_topspin_defence_and_lob_at_their_cited_heights():
    fish, fish_speed, _, _ = _flown("fish")
    assert np.all((fish >= HODGES_FISH[0]) & (fish <= 1.15 * HODGES_FISH[1]))
    lob, lob_speed, lob_apex, _ = _flown("lob")
    assert np.all(lob >= STROKES["lob"].net_height[0]) and np.median(lob) > np.median(fish) + 0.25
    assert np.all(lob_apex < CAMERA_TOP)  # still seen by the cameras (the lower, spinnier lob of Hodges 1993)
    assert np.all(lob_speed < 6.0) and np.all(fish_speed < 8.0)  # high balls are slow at the net
    drive_speed = _flown("drive")[1]
    assert np.median(drive_speed) > np.median(fish_speed) + 2.0


def test_default_sessions_spread_over_the_net_like_human_play():
    """Issue 41's bar on the default config's 4 sessions (12 rallies each): the good shots' net-crossing
    height spreads >= 15 cm between p10 and p90, and >= 8 % cross more than 0.25 m over the net."""
    crossings, lanes = [], []
    for k in range(4):
        rec, *_ = simulate_rallies(12, FaultRates(), rng_for(DEFAULT_SEED, "twin_simulate", f"s{k:02d}"))
        ball = pd.DataFrame(np.vstack(rec.ball), columns=["time_ns", "x", "y", "z", "vx", "vy", "vz", "wx",
                                                          "wy", "wz", "rally", "shot"])
        shots = pd.DataFrame(rec.shots)
        crossings.append(net_crossings(ball, shots))
        good = shots[shots.outcome == "ok"]
        lanes.append(good.strike_x * good.side)  # the dataset's mirrored frame
    crossings = pd.concat(crossings)
    p10, p90 = np.percentile(crossings.height, [10, 90])
    assert p90 - p10 >= 0.15
    assert (crossings.height > HIGH_OVER_NET).mean() >= 0.08
    lanes = pd.concat(lanes)
    shares = [(lanes < -0.25).mean(), lanes.between(-0.25, 0.25).mean(), (lanes > 0.25).mean()]
    np.testing.assert_allclose(shares, [0.18, 0.36, 0.45], atol=0.05)  # the paper's Table 2


def _ball_and_shots():
    """Two good shots and a fault, on straight 1 kHz samples: shot 0 crosses y = 0 at z = 0.45 m moving at
    5 m/s, shot 1 at z = 0.20 m at 10 m/s, shot 2 (a net) is left out."""
    rows = []
    for shot, (z, speed) in enumerate([(0.45, 5.0), (0.20, 10.0), (0.16, 7.0)]):
        y = np.linspace(1.0, -1.0, 201) + 0.0025  # no sample exactly on the net plane
        vy = -speed * np.ones_like(y)
        rows.append(pd.DataFrame({"time_ns": shot * 10**9 + np.arange(201) * 10**6, "x": 0.0, "y": y,
                                  "z": z, "vx": 0.0, "vy": vy, "vz": 0.0, "wx": 0.0, "wy": 0.0, "wz": 0.0,
                                  "rally": 0, "shot": shot}))
    shots = pd.DataFrame({"rally": [0, 0, 0], "shot": [0, 1, 2], "outcome": ["ok", "ok", "net"],
                          "stroke": ["lob", "drive", "drive"]})
    return pd.concat(rows, ignore_index=True), shots


def test_net_crossings_interpolate_height_over_the_tape_and_speed():
    ball, shots = _ball_and_shots()
    crossings = net_crossings(ball, shots)
    assert list(crossings["shot"]) == [0, 1]
    np.testing.assert_allclose(crossings["height"], [0.45 - NET_HEIGHT, 0.20 - NET_HEIGHT], atol=1e-12)
    np.testing.assert_allclose(crossings["speed"], [5.0, 10.0])
    assert list(crossings["stroke"]) == ["lob", "drive"]


def test_net_table_rows_shares_and_the_ball_gun_column():
    ball, shots = _ball_and_shots()
    crossings = net_crossings(ball, shots)
    table = net_table(crossings, [{"speed_in": 6.0}, {"speed_in": 8.0}], [{"speed_in": 5.0}] * 3)
    table = table.set_index(["statistic", "stroke"])
    high = table.loc[(STATISTICS["net_high_share"][0], "all")]
    assert high["twin"] == pytest.approx(0.5) and high["n"] == 2  # 0.2975 m over the tape, and 0.0475 m
    height = table.loc[(STATISTICS["net_height"][0], "all")]
    assert height["twin"] == pytest.approx(np.median([0.45, 0.20]) - NET_HEIGHT)
    assert np.isnan(height["real"])  # the ball gun's recordings carry no net position
    bounce = table.loc[(STATISTICS["bounce_speed"][0], "all")]
    assert bounce["twin"] == pytest.approx(7.0) and bounce["real"] == pytest.approx(5.0)
    assert "Hodges" in table.loc[(STATISTICS["net_height"][0], "lob"), "source"]
    assert table.loc[(STATISTICS["net_speed"][0], "drive"), "published (human play)"] == NOT_FOUND
    # no stroke's net height is measured in print but topspin defence's and the lob's coaching figures: the
    # others' aimed ranges are labelled the project's choice
    low, high = STROKES["drive"].net_height
    assert table.loc[(STATISTICS["net_height"][0], "drive"), "published (human play)"] == (
        f"no published measurement found: the twin's aim, {low:.2f}-{high:.2f} m over the net, is the "
        "project's choice")
    assert "project's choice" not in table.loc[(STATISTICS["net_height"][0], "lob"), "published (human play)"]


def test_tiny_run_reports_the_net_section(tiny_run):
    table = pd.read_csv(tiny_run / "reports/tables/twin_vs_real.csv")
    net = table[table["section"] == "net"].set_index(["statistic", "stroke"])
    height = net.loc[(STATISTICS["net_height"][0], "all")]
    assert height["n"] > 0 and height["twin_p10"] <= height["twin"] <= height["twin_p90"]
    assert height["twin_p10"] > 0  # every good shot clears the tape
    bounce = net.loc[(STATISTICS["bounce_speed"][0], "all")]
    assert np.isfinite(bounce[["twin", "real"]].astype(float)).all()
    text = (tiny_run / "reports/tables/twin_vs_real.md").read_text()
    assert "## Net-crossing height and speed at the net" in text
