"""Real MPI ball-gun flights: loading, bounce detection, plausible statistics, twin vs real."""

import json
from pathlib import Path

import numpy as np
import pytest

from pingpong.twin.ball import BallParams, simulate_flight
from pingpong.twin.realdata import (
    compare_flights_table,
    find_bounce,
    fit_params_to_real,
    flight_stats,
    load_real_flights,
)

FOLDER = Path(__file__).resolve().parents[1] / "data/realdata/mpi_ball_gun"


@pytest.fixture(scope="module")
def flights():
    return load_real_flights(FOLDER)


@pytest.fixture(scope="module")
def real_stats(flights):
    return [flight_stats(f["times"], f["positions"], f["velocities"]) for f in flights]


def test_loads_all_flights(flights):
    assert len(flights) == 106
    for f in flights:
        assert f["positions"].shape == f["velocities"].shape and f["positions"].shape[1] == 3
        assert np.all(np.diff(f["times"]) > 0)
        assert f["dt"] == pytest.approx(0.0109, abs=0.0005)  # the README's ~10.9 ms


@pytest.mark.parametrize("content, message", [
    ("{not json", "not valid JSON"),
    ('{"other": []}', "key 'ob'"),
    ('{"ob": [[1, 2, 3]]}', "shape"),
    ('{"ob": ' + json.dumps([[0.0, 0.0, 0.0, 1.0, 1.0, 1.0]] * 24 + [[0, 0, None, 1, 1, 1]]) + "}", "row 24"),
])
def test_malformed_file_is_named(tmp_path, content, message):
    (tmp_path / "good.json").write_text(json.dumps({"ob": [[i * 0.01, 0, 0, 1, 0, 0] for i in range(30)]}))
    (tmp_path / "broken.json").write_text(content)
    with pytest.raises(ValueError, match=message) as info:
        load_real_flights(tmp_path)
    assert "broken.json" in str(info.value)


def test_bounce_found_near_the_z_minimum(flights, real_stats):
    for f, s in zip(flights, real_stats, strict=True):
        z = f["positions"][:, 2]
        i = s["bounce_index"]
        # the lowest point before the ball leaves the table (some flights end lower, off the table's end)
        assert z[i] <= z[: i + 10].min() + 1e-12
        assert f["velocities"][i - 3, 2] < 0 < f["velocities"][i + 4, 2]  # filtered v_z turns ~3 samples late
        assert abs(s["bounce_time"] - f["times"][i]) < 0.011  # within a sample of the lowest one


def test_stats_are_physically_plausible(real_stats):
    med = {k: np.median([s[k] for s in real_stats]) for k in real_stats[0] if np.ndim(real_stats[0][k]) == 0}
    assert 0.8 < med["restitution_z"] < 1.0  # table tennis table: ~0.9
    assert 0.4 < med["hspeed_ratio"] < 1.0  # friction slows the ball without backspin reversing it
    assert 0.6 < med["speed_ratio"] < 1.0
    assert 3 < med["speed_in"] < 7  # a ball gun at 3-6 m/s
    assert 10 < med["speed_loss_pct_per_s"] < 60  # k_D |v| with k_D ~ 0.1-0.16 /m at ~4.5 m/s
    assert np.radians(30) < med["angle_in"] < np.radians(70)


def test_fit_recovers_plausible_params(flights):
    fit = fit_params_to_real(flights)
    p = fit["params"]
    assert 0.35 < p.drag_coefficient < 0.7
    assert 0.85 < p.table_restitution < 0.97
    assert 0.05 < p.table_friction < 0.35


def test_twin_ball_gun_flights_match_real_ones(flights, real_stats):
    # launch the twin like the ball gun: each real flight's first state, moved so it bounces on the table
    params = BallParams()
    bounce_at = np.median([s["bounce_position"] for s in real_stats], axis=0)
    offset = bounce_at - [0.0, -0.6, params.radius]
    twin_stats = []
    for f in flights:
        flight = simulate_flight(f["positions"][0] - offset, f["velocities"][0], np.zeros(3), params,
                                 t_max=1.0)
        assert flight.events[0].kind == "bounce"
        twin_stats.append(flight_stats(flight.times, flight.positions, flight.velocities))
    table = compare_flights_table(twin_stats, real_stats).set_index("quantity")
    twin, real = table["twin_median"], table["real_median"]
    # the twin has no spin and one set of coefficients, so medians agree to what the unknown ball-gun
    # spin (~+-0.5 m/s^2 of Magnus), the fitted coefficients' spread and the real velocity filter allow:
    # speeds and ratios to 8%, angles to 5 deg, drag loss rates to 35%.
    for q in ("speed before the bounce", "speed after the bounce", "speed ratio out/in",
              "horizontal velocity ratio out/in", "vertical restitution"):
        assert twin[q] == pytest.approx(real[q], rel=0.08), q
    for q in ("incidence angle to the table", "rebound angle to the table"):
        assert twin[q] == pytest.approx(real[q], abs=5.0), q
    for q in ("energy-speed loss before the bounce", "horizontal speed loss before the bounce"):
        assert twin[q] == pytest.approx(real[q], rel=0.35), q


def test_find_bounce_rejects_a_flight_without_one():
    t = np.linspace(0, 0.5, 50)
    falling = np.column_stack([t, t, 1.0 - 4.9 * t**2])
    with pytest.raises(ValueError, match="no bounce"):
        find_bounce(t, falling)
