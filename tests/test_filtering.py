"""Event-aware zero-phase low-pass: noise reduction on simulated flights, bounces kept, lines, NaN."""

import numpy as np
import pytest

from pingpong.curation.filtering import lowpass, lowpass_between_events
from pingpong.twin.ball import aim_shots, simulate_flight, stop_at_y
from pingpong.twin.realdata import find_bounce, load_real_flights

FS = 100.0
CUTOFF = 10.0
NOISE = 0.003  # m, triangulation noise


def sampled(flight, phase):
    """The flight sampled at 100 Hz from t = phase (s), like the cameras."""
    t = np.arange(phase, flight.times[-1], 1 / FS)
    return t, np.column_stack([np.interp(t, flight.times, flight.positions[:, k]) for k in range(3)])


@pytest.fixture(scope="module")
def noisy_flights():
    """Simulated serves-to-receiver flights with one or two bounces: (times, truth, noisy, bounce frames)."""
    rng = np.random.default_rng(0)
    n = 20
    p0 = np.column_stack([rng.uniform(-0.5, 0.5, n), rng.uniform(1.5, 1.8, n), rng.uniform(0.1, 0.4, n)])
    target = np.column_stack([rng.uniform(-0.6, 0.6, n), rng.uniform(-1.2, -0.3, n)])
    spin = rng.normal(0, 1, (n, 3)) * [60, 30, 30]  # rad/s: top/backspin, sidespin
    v0, _ = aim_shots(p0, target, spin)
    out = []
    for k in range(n):
        flight = simulate_flight(p0[k], v0[k], spin[k], t_max=1.0, stop=stop_at_y(-2.0))
        t, truth = sampled(flight, rng.uniform(0, 1 / FS))
        frames = [int(np.argmin(np.abs(t - e.time))) for e in flight.events if e.kind == "bounce"]
        assert frames
        out.append((t, truth, truth + rng.normal(0, NOISE, truth.shape), frames))
    return out


def rms(a):
    return float(np.sqrt(np.mean(a**2)))


def test_filter_reduces_noise_on_simulated_flights(noisy_flights):
    raw, filtered = [], []
    for t, truth, noisy, frames in noisy_flights:
        smooth = lowpass_between_events(t, noisy, frames, CUTOFF, FS)
        assert np.array_equal(smooth[frames], noisy[frames])  # the contact samples are kept as measured
        raw.append(rms(noisy - truth))
        filtered.append(rms(smooth - truth))
    # measured: 3.0 mm -> 1.3 mm median RMS (10 Hz, 4th order)
    assert np.median(filtered) < 0.55 * np.median(raw)
    assert np.all(np.array(filtered) < np.array(raw))


def test_cutting_at_the_bounce_keeps_it_sharp(noisy_flights):
    # near the bounce a filter run across it rounds the V off; cut there, it does not
    cut, across = [], []
    for t, truth, noisy, frames in noisy_flights:
        near = np.concatenate([np.arange(f - 3, f + 4) for f in frames])
        near = near[(near >= 0) & (near < len(t))]
        cut.append(rms((lowpass_between_events(t, noisy, frames, CUTOFF, FS) - truth)[near, 2]))
        across.append(rms((lowpass_between_events(t, noisy, [], CUTOFF, FS) - truth)[near, 2]))
    assert np.median(cut) < 0.3 * np.median(across)  # measured 1.6 mm against 9.5 mm (z, +-3 frames)


def test_real_bounces_stay_on_their_frame():
    # the MPI flights are sampled on a 5.45 ms tick with dropped ticks: filtered on that uniform grid
    flights = load_real_flights("/work/shared/realdata/mpi_ball_gun")
    fs_tick = 2 / np.median([f["dt"] for f in flights])
    moved_across = 0
    for f in flights:
        i = find_bounce(f["times"], f["positions"])
        smooth = lowpass_between_events(f["times"], f["positions"], [i], CUTOFF, fs_tick)
        assert find_bounce(f["times"], smooth) == i, f["name"]
        near = slice(i - 10, i + 11)
        assert smooth[near, 2].min() >= f["positions"][i, 2] - 1e-3  # nothing pulled into the table
        across = lowpass_between_events(f["times"], f["positions"], [], CUTOFF, fs_tick)
        moved_across += find_bounce(f["times"], across) != i
    assert moved_across > 10  # the check has teeth: filtering across the bounce moves ~30 of 106


@pytest.mark.parametrize("n", [4, 7, 20, 300])
def test_lines_and_parabolas_pass_unchanged(n):
    t = 0.5 + np.arange(n) / FS
    line = np.column_stack([0.3 + 4.0 * t, -1.0 - 7.0 * t, 0.2 + 0.5 * t])
    assert np.allclose(lowpass_between_events(t, line, [], CUTOFF, FS), line, atol=1e-9)
    parabola = 0.3 + 2.0 * t - 4.905 * t**2
    # a 4th-order zero-phase Butterworth passes polynomials of degree < 8; the start-up transient of the
    # padded ends leaves ~1e-5 m
    assert np.allclose(lowpass_between_events(t, parabola, [], CUTOFF, FS), parabola, atol=2e-5)


def test_nan_gaps_stay_and_split_the_pieces():
    t = np.arange(100) / FS
    signal = np.where(t < 0.5, 1.0, 2.0)  # a step hidden in a gap: each side is constant
    signal[45:55] = np.nan
    out = lowpass_between_events(t, signal, [], CUTOFF, FS)
    assert np.isnan(out[45:55]).all()
    assert np.allclose(out[:45], 1.0) and np.allclose(out[55:], 2.0)


def test_columns_are_filtered_independently_with_their_own_gaps():
    rng = np.random.default_rng(1)
    signal = np.sin(np.arange(200) / FS * 2 * np.pi)[:, None] + rng.normal(0, 0.01, (200, 2))
    signal[80:90, 1] = np.nan
    out = lowpass(signal, CUTOFF, FS)
    assert np.isnan(out[80:90, 1]).all() and np.isfinite(out[:, 0]).all()
    assert np.isfinite(out[:80, 1]).all() and np.isfinite(out[90:, 1]).all()


def test_pieces_of_three_samples_are_kept_and_events_split():
    t = np.arange(30) / FS
    signal = np.random.default_rng(2).normal(size=30)
    signal[3] = np.nan
    out = lowpass_between_events(t, signal, [20], CUTOFF, FS)
    assert np.array_equal(out[:3], signal[:3])  # 3 samples before the gap
    assert out[20] == signal[20]


def test_lowpass_keeps_slow_pose_motion_and_removes_jitter():
    t = np.arange(500) / FS
    slow = 0.2 * np.sin(2 * np.pi * 1.0 * t)
    jitter = 0.01 * np.sin(2 * np.pi * 30.0 * t)
    out = lowpass(slow + jitter, 6.0, FS)
    error = np.abs(out - slow)
    assert error[10:-10].max() < 1e-3  # 30 Hz through a 6 Hz 4th-order filter twice: ~1e-6 gain
    assert error.max() < 3e-3  # the ends extrapolate 0.25 s quadratics of a 1 Hz sine: ~2 mm of 200


def test_bad_cutoff_is_named():
    with pytest.raises(ValueError, match="Nyquist"):
        lowpass(np.zeros(50), 60.0, FS)
