"""The visual servo's strike estimates (robot.servo) on simulated flights, and their accuracy report.

Flights are the twin's (twin.ball.simulate_flight, each ball's coefficients varied by
sample_ball_params so that the model fit's nominal ball is not exact), sampled at 100 Hz with 2 mm
Gaussian noise: shots of 5-15 m/s towards -y from y = 1.3..1.6 m, z = 0.1..0.4 m, with up to 100 rev/s
of topspin, backspin and sidespin, aimed (aim_shots) at the robot's half of the table; shots that miss
it, hit the net or bounce twice before the strike line are dropped.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pingpong.frames import STRIKE_Y, TABLE_HALF_LENGTH
from pingpong.reports.servo_accuracy import servo_accuracy, strike_crossing
from pingpong.robot.servo import (
    NO_CROSSING,
    OK,
    SERVO_FITS,
    STATUSES,
    TOO_FEW_POINTS,
    model_strike_estimate,
    paper_strike_estimate,
    split_at_bounce,
)
from pingpong.twin.ball import aim_shots, sample_ball_params, simulate_flight, stop_at_y

FRAME_DT = 0.01  # s
NOISE = 0.002  # m, std of a seen ball centre
PAST_LINE = 0.3  # m: flights run on past the strike line so that tracks cross it


def sampled(flight, rng: np.random.Generator | None = None):
    """(frame times (N,), ball centres (N, 3)) of a flight at 100 Hz, with NOISE if rng is given."""
    times = np.arange(0.0, flight.times[-1], FRAME_DT)
    seen = np.column_stack([np.interp(times, flight.times, flight.positions[:, k]) for k in range(3)])
    return times, seen if rng is None else seen + NOISE * rng.standard_normal(seen.shape)


def aimed_flight(p_hit, target, spin, speed: float, params=None):
    """The flight of a shot from p_hit bouncing at target (x, y) about `speed` m/s, or None if unaimable."""
    p_hit, target = np.asarray(p_hit, float), np.asarray(target, float)
    kwargs = {} if params is None else {"params": params}
    flight_time = np.linalg.norm(target - p_hit[:2]) / speed
    try:
        v0, _ = aim_shots(p_hit, target, spin, flight_time=flight_time, **kwargs)
    except ValueError:
        return None
    return simulate_flight(p_hit, v0[0], spin, stop=stop_at_y(STRIKE_Y - PAST_LINE), **kwargs), v0[0]


def realistic_shot(rng: np.random.Generator):
    """One flight as in the module docstring, or None when it is rejected."""
    p_hit = [rng.uniform(-0.6, 0.6), rng.uniform(1.3, 1.6), rng.uniform(0.1, 0.4)]
    target = np.array([rng.uniform(-0.65, 0.65), rng.uniform(-1.25, -0.2)])
    heading = (target - p_hit[:2]) / np.linalg.norm(target - p_hit[:2])
    topspin_axis = np.array([-heading[1], heading[0], 0.0])
    angle = rng.uniform(0, 2 * np.pi)  # topspin, sidespin, backspin and their mixes
    axis = np.cos(angle) * topspin_axis + np.sin(angle) * np.array([0.0, 0.0, 1.0])
    spin = 2 * np.pi * rng.uniform(0, 100) * axis  # rad/s
    aimed = aimed_flight(p_hit, target, spin, rng.uniform(5, 15), sample_ball_params(rng))
    if aimed is None:
        return None
    flight, v0 = aimed
    kinds = [event.kind for event in flight.events]
    on_robot_half = -TABLE_HALF_LENGTH <= flight.events[0].position[1] <= 0
    if kinds != ["bounce", "stop"] or not on_robot_half or not 5 <= np.linalg.norm(v0) <= 15:
        return None
    return flight


def realistic_flights(n: int, seed: int):
    """n accepted flights as (truth Flight, noisy frame times, noisy centres)."""
    rng = np.random.default_rng(seed)
    flights = []
    while len(flights) < n:
        if (flight := realistic_shot(rng)) is not None and flight.positions[-1, 1] <= STRIKE_Y:
            flights.append((flight, *sampled(flight, rng)))
    return flights


FLIGHTS = realistic_flights(60, seed=7)


def true_crossing(flight) -> tuple[np.ndarray, float]:
    return strike_crossing(flight.times, flight.positions, STRIKE_Y)


def estimates_at(fit, frame: int, flights=FLIGHTS):
    """(estimate, true (x, z)) per flight not yet past the strike line at `frame`."""
    out = []
    for flight, times, seen in flights:
        cross_xz, t_cross = true_crossing(flight)
        if t_cross > frame * FRAME_DT:
            k = times <= frame * FRAME_DT + 1e-9
            out.append((fit(times[k], seen[k]), cross_xz))
    return out


def errors_cm(pairs) -> np.ndarray:
    return np.array([100 * np.linalg.norm(e.strike_xz - xz) for e, xz in pairs if e.ok])


# ---------------------------------------------------------------- accuracy on realistic shots

def test_model_fit_beats_the_paper_fit_at_20_frames():
    """Measured on FLIGHTS: model median 2.0 cm, p90 5.2 cm; paper median 9.8 cm. Bounds: model median
    < 3 cm and under half the paper's, every model estimate made."""
    model, paper = estimates_at(model_strike_estimate, 20), estimates_at(paper_strike_estimate, 20)
    assert all(e.ok for e, _ in model)
    assert np.median(errors_cm(model)) < 3.0
    assert np.median(errors_cm(model)) < 0.5 * np.median(errors_cm(paper))


def test_model_fit_improves_with_frames_and_stays_ahead():
    """Median error falls from +10 to +20 frames for the model fit (measured 6.6, 3.3, 2.0 cm) and is
    below the paper fit's at each frame (measured 16.7, 13.4, 9.8 cm)."""
    medians = {name: [np.median(errors_cm(estimates_at(fit, f))) for f in (10, 15, 20)]
               for name, fit in SERVO_FITS.items()}
    assert medians["model"][0] > medians["model"][1] > medians["model"][2]
    assert all(m < p for m, p in zip(medians["model"], medians["paper"], strict=True))


def test_elastic_bounce_biases_the_paper_height_and_the_model_bounce_does_not():
    """Before the bounce is seen (+10 frames) the paper fit reflects the fall elastically: measured median
    height error +6.9 cm. The model's restitution and friction bounce: measured -0.3 cm.
    Bounds: paper > +4 cm, model within +-1.5 cm."""
    def height_bias(fit):
        return 100 * np.median([e.strike_xz[1] - xz[1] for e, xz in estimates_at(fit, 10) if e.ok])

    assert height_bias(paper_strike_estimate) > 4.0
    assert abs(height_bias(model_strike_estimate)) < 1.5


def test_model_fit_after_the_bounce_is_seen():
    """With at least three post-bounce points the model fit uses them (with the model bounce's spin as
    prior): measured median 0.5 cm, p90 2.4 cm over 46 cases. Bounds: median < 1.5 cm, p90 < 5 cm."""
    pairs = []
    for flight, times, seen in FLIGHTS:
        cross_xz, t_cross = true_crossing(flight)
        for frame in (30, 40, 50):
            k = times <= frame * FRAME_DT + 1e-9
            if t_cross > frame * FRAME_DT and k.sum() - split_at_bounce(seen[k])[1] >= 3:
                pairs.append((model_strike_estimate(times[k], seen[k]), cross_xz))
    assert len(pairs) >= 20
    assert all(e.ok for e, _ in pairs)
    errors = errors_cm(pairs)
    assert np.median(errors) < 1.5 and np.percentile(errors, 90) < 5.0


# ---------------------------------------------------------------- the paper fit's failure cases

def test_rising_table_height_crossing_after_the_hit_is_not_a_bounce():
    """A ball hit from below the table's height (beyond its end) rises through the ball's resting height
    right after the hit. That crossing once counted as the bounce (strike heights of -4 to -5 m here);
    now only a descending crossing does. Noise-free; measured height errors: paper 0.4-7.6 cm (its
    elastic bounce), model < 1 cm."""
    for spin in ([0.0, 0.0, 0.0], [300.0, 0.0, 0.0]):
        flight, _ = aimed_flight([0.1, 1.45, -0.02], [0.2, -0.6], spin, speed=5.0)
        times, seen = sampled(flight)
        cross_xz, _ = true_crossing(flight)
        for frame in (10, 15, 20):
            k = times <= frame * FRAME_DT + 1e-9
            paper, model = paper_strike_estimate(times[k], seen[k]), model_strike_estimate(times[k], seen[k])
            assert paper.ok and abs(paper.strike_xz[1] - cross_xz[1]) < 0.15
            assert model.ok and np.linalg.norm(model.strike_xz - cross_xz) < 0.02


@settings(max_examples=20, deadline=None)
@given(st.floats(-0.05, 0.015), st.floats(-400, 400), st.floats(4.0, 8.0))
def test_no_bogus_negative_height_from_low_hits(z_hit, topspin, speed):
    """Property over hits from below the ball's resting height: no strike height below the table's
    underside (-0.1 m) from either fit, at +10 to +20 frames."""
    aimed = aimed_flight([0.0, 1.45, z_hit], [0.1, -0.6], [topspin, 0.0, 0.0], speed)
    if aimed is None or aimed[0].positions[-1, 1] > STRIKE_Y:
        return
    times, seen = sampled(aimed[0])
    for frame in (10, 15, 20):
        k = times <= frame * FRAME_DT + 1e-9
        for fit in SERVO_FITS.values():
            estimate = fit(times[k], seen[k])
            assert not estimate.ok or estimate.strike_xz[1] > -0.1


def test_drag_slowed_paper_quadratic_turns_back_and_the_model_still_estimates():
    """A slow chop (4.6 m/s, 100 rev/s backspin): drag and lift slow y so much that the paper's quadratic
    in y turns back before the strike line. That is the stated status no_crossing, not a silent nan;
    the model fit flies drag through: measured error 0.7-4.0 cm, bound 6 cm. Noise-free."""
    flight, _ = aimed_flight([0.0, 1.45, 0.3], [0.1, -0.7], [-600.0, 0.0, 0.0], speed=3.0)
    times, seen = sampled(flight)
    cross_xz, _ = true_crossing(flight)
    for frame in (10, 15, 20):
        k = times <= frame * FRAME_DT + 1e-9
        paper, model = paper_strike_estimate(times[k], seen[k]), model_strike_estimate(times[k], seen[k])
        assert paper.status == NO_CROSSING and np.isnan(paper.strike_xz).all() and np.isnan(paper.time_s)
        assert model.ok and np.linalg.norm(model.strike_xz - cross_xz) < 0.06


# ---------------------------------------------------------------- statuses and interfaces

@pytest.mark.parametrize("fit", SERVO_FITS.values(), ids=SERVO_FITS.keys())
def test_too_few_points_is_its_own_status(fit):
    flight, times, seen = FLIGHTS[0]
    for k in range(3):
        assert fit(times[:k], seen[:k]).status == TOO_FEW_POINTS
    gappy = seen[:6].copy()
    gappy[[1, 3, 4]] = np.nan  # frames without a ball are left out: 3 of 6 remain, then 2
    assert fit(times[:6], gappy).status != TOO_FEW_POINTS
    gappy[5] = np.nan
    estimate = fit(times[:6], gappy)
    assert estimate.status == TOO_FEW_POINTS and np.isnan(estimate.strike_xz).all()


def test_missing_frames_are_fine():
    """Every third frame missing (nan) at +20: the model fit's median error stays < 3 cm."""
    pairs = []
    for flight, times, seen in FLIGHTS:
        cross_xz, t_cross = true_crossing(flight)
        k = times <= 0.2 + 1e-9
        if t_cross > 0.2:
            gappy = seen[k].copy()
            gappy[1::3] = np.nan
            pairs.append((model_strike_estimate(times[k], gappy), cross_xz))
    assert np.median(errors_cm(pairs)) < 3.0


def test_a_seen_crossing_is_interpolated():
    flight, times, seen = FLIGHTS[0]
    cross_xz, t_cross = true_crossing(flight)
    k = times <= t_cross + 2 * FRAME_DT
    estimate = model_strike_estimate(times[k], seen[k])
    assert estimate.ok and np.linalg.norm(estimate.strike_xz - cross_xz) < 3 * NOISE
    assert estimate.time_s == pytest.approx(t_cross, abs=1e-3)


def test_a_low_point_off_the_table_is_no_bounce():
    """The lowest point counts as the bounce only over the table and near its surface."""
    t = np.arange(8) * FRAME_DT
    over = np.column_stack([np.zeros(8), 0.5 - 5 * t, 0.05 + 4 * (t - 0.03) ** 2 * 40])
    assert split_at_bounce(over) == (3, 4)
    off = over + [1.0, 0.0, 0.0]  # beside the table
    assert split_at_bounce(off) == (8, 8)
    high = over + [0.0, 0.0, 0.2]  # a flight's apex-like dip well above the table
    assert split_at_bounce(high) == (8, 8)


tracks = st.integers(0, 25).flatmap(lambda n: st.tuples(
    st.lists(st.floats(0.004, 0.03), min_size=n, max_size=n),
    st.lists(st.tuples(st.floats(-3, 3), st.floats(-3, 3), st.floats(-1, 2)), min_size=n, max_size=n),
    st.lists(st.booleans(), min_size=n, max_size=n)))


@settings(max_examples=150, deadline=None)
@given(tracks)
def test_every_answer_has_a_stated_status(track):
    """Any points (nonsense included): a status from the fixed set; an estimate is finite exactly when
    the status is ok, and all nan otherwise."""
    steps, positions, missing = track
    times = np.cumsum(steps)
    seen = np.array(positions, float).reshape(-1, 3)
    seen[np.array(missing, bool)] = np.nan
    for fit in SERVO_FITS.values():
        estimate = fit(times, seen)
        assert estimate.status in STATUSES
        finite = np.isfinite(estimate.strike_xz).all() and np.isfinite(estimate.time_s)
        assert finite == (estimate.status == OK)
        assert finite or (np.isnan(estimate.strike_xz).all() and np.isnan(estimate.time_s))


# ---------------------------------------------------------------- the accuracy report

def test_servo_accuracy_table():
    """Columns, counts and ordering on a few flights, with missing frames and a flight that never
    crosses (skipped)."""
    tracks = []
    for _, times, seen in FLIGHTS[:12]:
        keep = np.ones(len(times), bool)
        keep[5::7] = False  # missing frames: absent samples
        tracks.append((times[keep], seen[keep]))
    short = FLIGHTS[0][2][FLIGHTS[0][2][:, 1] > 0.0]  # stops before the net: never crosses
    tracks.append((FLIGHTS[0][1][:len(short)], short))
    table = servo_accuracy(tracks)
    assert list(table.columns) == ["fit", "frames_after_hit", "n_flights", "median_error_cm",
                                   "p90_error_cm", "no_estimate_share", *[f"n_{s}" for s in STATUSES]]
    assert len(table) == 2 * 3 and set(table["fit"]) == {"paper", "model"}
    assert (table["n_flights"] <= 12).all() and (table["n_flights"] > 0).all()
    counts = table[[f"n_{s}" for s in STATUSES]].sum(axis=1)
    assert (counts == table["n_flights"]).all()
    assert table["no_estimate_share"].between(0, 1).all()
    assert (table["median_error_cm"] <= table["p90_error_cm"]).all()
    by = table.set_index(["fit", "frames_after_hit"])
    for frame in (10, 15, 20):
        assert by.loc[("model", frame), "median_error_cm"] < by.loc[("paper", frame), "median_error_cm"]
    assert by.loc[("model", 20), "median_error_cm"] < 5.0
