"""Mirroring, two-line labels, strike points, and rally-grouped splits."""

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation

from pingpong.curation.labels import (
    MIRROR,
    fit_two_lines,
    labels_of_path,
    measured_strike_point,
    mirror_frames,
    mirror_labels,
    mirror_points,
    mirror_rotations,
    reflect_frames,
    reflect_labels,
    strike_point_from_labels,
    x_of_y,
)
from pingpong.curation.splits import split_by_rally
from pingpong.frames import MODEL_JOINTS, N_INPUT, STRIKE_Y, region_of
from pingpong.twin.ball import aim_shots, simulate_flight, stop_at_y

finite = st.floats(-5, 5, allow_nan=False)
slopes = st.floats(-0.5, 0.5, allow_nan=False)


def two_line_path(a1, a2, b, n=60):
    y = np.linspace(1.6, -1.6, n)
    return y, x_of_y(a1, a2, b, y)


# ---------------------------------------------------------------- mirroring

@given(arrays(float, (7, 3), elements=finite))
def test_mirroring_points_twice_is_the_identity(points):
    assert np.array_equal(mirror_points(mirror_points(points)), points)


@given(arrays(float, (4, N_INPUT), elements=finite))
def test_mirroring_frames_twice_is_the_identity(frames):
    assert np.allclose(mirror_frames(mirror_frames(frames)), frames, atol=0)


@given(st.integers(0, 2**32 - 1))
def test_mirrored_rotations_stay_proper_and_twice_is_identity(seed):
    R = Rotation.random(5, random_state=seed).as_matrix()
    M = mirror_rotations(R)
    assert np.allclose(np.linalg.det(M), 1.0)  # a rotation: right-handed frames stay right-handed
    assert np.allclose(M @ M.transpose(0, 2, 1), np.eye(3))
    assert np.allclose(mirror_rotations(M), R)


def test_mirror_is_a_rotation_by_pi_about_z_and_frames_follow_the_layout():
    assert np.allclose(MIRROR, Rotation.from_rotvec([0, 0, np.pi]).as_matrix())
    rng = np.random.default_rng(0)
    frame = rng.normal(size=N_INPUT)
    R = Rotation.random(random_state=1).as_matrix()
    frame[27:36] = R.ravel()  # row-major paddle rotation after 8 joints and the paddle position
    out = mirror_frames(frame)
    assert np.allclose(out[:27].reshape(9, 3), frame[:27].reshape(9, 3) * [-1, -1, 1])
    assert np.allclose(out[27:36].reshape(3, 3), MIRROR @ R)
    assert np.allclose(out[36:], frame[36:] * [-1, -1, 1])
    # the paddle's own axes, seen from the mirrored frame, point where the mirrored points go
    face_point = frame[24:27] + R @ [0.0, 0.0, 0.1]
    assert np.allclose(mirror_points(face_point), out[24:27] + out[27:36].reshape(3, 3) @ [0.0, 0.0, 0.1])
    with pytest.raises(ValueError, match="39"):
        mirror_frames(np.zeros(38))


# ---------------------------------------------------------------- reflection (training augmentation)

@given(arrays(float, (4, N_INPUT), elements=finite))
def test_reflecting_frames_twice_is_the_identity(frames):
    assert np.allclose(reflect_frames(reflect_frames(frames)), frames, atol=0)


@given(st.integers(0, 2**32 - 1))
def test_reflection_is_x_to_minus_x_for_every_point_of_the_body_and_paddle(seed):
    rng = np.random.default_rng(seed)
    frame = rng.normal(size=N_INPUT)
    R = Rotation.random(random_state=seed).as_matrix()
    frame[27:36] = R.ravel()
    out = reflect_frames(frame)
    joints, reflected = frame[:24].reshape(8, 3), out[:24].reshape(8, 3)
    for k, name in enumerate(MODEL_JOINTS):  # the right shoulder's place is now the left's, x negated
        other = {"R": "L", "L": "R"}[name[0]] + name[1:]
        assert np.allclose(reflected[MODEL_JOINTS.index(other)], joints[k] * [-1, 1, 1])
    assert np.allclose(out[[24, 25, 26, 36, 37, 38]], frame[[24, 25, 26, 36, 37, 38]] * [-1, 1, 1, -1, 1, 1])
    R2 = out[27:36].reshape(3, 3)
    assert np.isclose(np.linalg.det(R2), 1.0) and np.allclose(R2 @ R2.T, np.eye(3))
    # the tip (body x) and a point on the face's normal (body z) land on the reflected world points
    for body_point in ([0.1, 0.0, 0.0], [0.0, 0.0, 0.1]):
        world = frame[24:27] + R @ body_point
        assert np.allclose(world * [-1, 1, 1], out[24:27] + R2 @ body_point)


@given(slopes, slopes, st.floats(-0.7, 0.7))
def test_reflected_labels_describe_the_reflected_path(a1, a2, b):
    y, x = two_line_path(a1, a2, b)
    assert np.allclose(x_of_y(*reflect_labels([a1, a2, b]), y), -x)
    assert np.allclose(reflect_frames(np.array([[0.3, 1.2, 0.2]])), [[-0.3, 1.2, 0.2]])  # ball-only frames
    with pytest.raises(ValueError, match="39"):
        reflect_frames(np.zeros(38))


# ---------------------------------------------------------------- labels

@given(slopes, slopes, st.floats(-0.7, 0.7))
def test_two_lines_are_recovered_exactly(a1, a2, b):
    y, x = two_line_path(a1, a2, b)
    assert np.allclose(fit_two_lines(y, x), (a1, a2, b), atol=1e-9)
    assert strike_point_from_labels(a1, a2, b) == pytest.approx(a2 * STRIKE_Y + b)


@given(slopes, slopes, st.floats(-0.7, 0.7), st.integers(0, 2**32 - 1))
@settings(max_examples=50)
def test_fit_of_the_mirrored_path_is_the_mirrored_fit(a1, a2, b, seed):
    y, x = two_line_path(a1, a2, b)
    x = x + np.random.default_rng(seed).normal(0, 0.01, len(x))  # noisy, so the fit is a real fit
    path = np.column_stack([x, y, np.zeros_like(y)])
    mirrored = mirror_points(path)
    assert np.allclose(fit_two_lines(mirrored[:, 1], mirrored[:, 0]), mirror_labels(*fit_two_lines(y, x)),
                       atol=1e-9)


def test_fit_skips_nan_and_leaves_an_unseen_side_undetermined():
    y, x = two_line_path(0.1, -0.2, 0.3)
    x[5] = np.nan
    assert np.allclose(fit_two_lines(y, x), (0.1, -0.2, 0.3))
    a1, a2, b = fit_two_lines(y[y >= 0], x[y >= 0])
    assert np.isnan(a2) and a1 == pytest.approx(0.1) and b == pytest.approx(0.3)
    with pytest.raises(ValueError, match="cannot fix"):
        fit_two_lines([1.0, np.nan], [0.0, 0.0])


def test_measured_strike_point_interpolates_and_is_nan_when_short():
    t = np.linspace(0, 1, 11)
    path = np.column_stack([0.1 + 0.2 * t, 1.6 - 3.5 * t, 0.3 - 0.1 * t])  # y = -1.40 at t = 6/7
    x, z = measured_strike_point(path)
    assert x == pytest.approx(0.1 + 0.2 * 3.0 / 3.5) and z == pytest.approx(0.3 - 0.1 * 3.0 / 3.5)
    assert np.isnan(measured_strike_point(path[:5])).all()
    assert list(region_of([-0.3, 0.0, 0.3])) == ["left", "centre", "right"]


def test_labels_predict_the_strike_point_of_simulated_returns():
    rng = np.random.default_rng(5)
    n = 40
    p0 = np.column_stack([rng.uniform(-0.6, 0.6, n), rng.uniform(1.5, 1.8, n), rng.uniform(0.1, 0.4, n)])
    target = np.column_stack([rng.uniform(-0.6, 0.6, n), rng.uniform(-1.2, -0.3, n)])
    spin = rng.normal(0, 1, (n, 3)) * [60, 30, 30]  # topspin/backspin about x, sidespin bends x(y)
    v0, _ = aim_shots(p0, target, spin)
    errors = []
    for k in range(n):
        flight = simulate_flight(p0[k], v0[k], spin[k], t_max=2.0, stop=stop_at_y(-1.7))
        t = np.arange(0, flight.times[-1], 0.01)
        camera = np.column_stack([np.interp(t, flight.times, flight.positions[:, j]) for j in range(3)])
        camera += rng.normal(0, 0.003, camera.shape)
        x_true, _ = measured_strike_point(flight.positions)
        errors.append(strike_point_from_labels(*labels_of_path(camera)) - x_true)
    errors = np.abs(errors)
    assert np.median(errors) < 0.02  # measured ~2 mm; 90th percentile ~6 mm
    assert np.percentile(errors, 90) < 0.03


# ---------------------------------------------------------------- splits

@st.composite
def hit_tables(draw, max_rallies=60):
    n_sessions = draw(st.integers(1, 4))
    rows = []
    for s in range(n_sessions):
        for r in range(draw(st.integers(1, max_rallies))):
            rows += [(f"s{s}", r)] * draw(st.integers(1, 8))
    table = pd.DataFrame(rows, columns=["session", "rally"])
    return table.sample(frac=1.0, random_state=draw(st.integers(0, 99)))  # rows in any order


@given(hit_tables(), st.integers(0, 2**32 - 1))
@settings(max_examples=60, deadline=None)
def test_rallies_stay_whole_and_every_hit_is_assigned(table, seed):
    out = split_by_rally(table, np.random.default_rng(seed))
    assert out.index.equals(table.index) and len(out) == len(table)
    assert set(out["split"]) <= {"train", "calibration", "test"}
    per_rally = out.groupby(["session", "rally"])[["split", "fold"]].nunique()
    assert (per_rally == 1).all().all()
    assert ((out["fold"] >= 0) == (out["split"] == "train")).all()
    assert out.loc[out["split"] == "train", "fold"].between(0, 4).all()
    again = split_by_rally(table, np.random.default_rng(seed))
    pd.testing.assert_frame_equal(out, again)


@given(st.integers(0, 2**32 - 1))
@settings(max_examples=20, deadline=None)
def test_fractions_and_folds_are_balanced_on_large_tables(seed):
    rng = np.random.default_rng(seed)
    sizes = rng.integers(1, 12, 600)  # 600 rallies, ~3600 hits
    table = pd.DataFrame({"session": np.repeat(rng.integers(0, 5, 600), sizes), "rally": np.repeat(
        np.arange(600), sizes)})
    out = split_by_rally(table, np.random.default_rng(seed), test_fraction=0.2, calibration_fraction=0.1)
    share = out["split"].value_counts(normalize=True)
    assert share["test"] == pytest.approx(0.2, abs=0.01)
    assert share["calibration"] == pytest.approx(0.1, abs=0.01)
    folds = out.loc[out["split"] == "train", "fold"].value_counts(normalize=True)
    assert len(folds) == 5 and np.allclose(folds, 0.2, atol=0.01)


def test_different_seeds_give_different_splits_and_bad_tables_are_named():
    table = pd.DataFrame({"session": "s", "rally": np.repeat(np.arange(50), 3)})
    a = split_by_rally(table, np.random.default_rng(0))
    b = split_by_rally(table, np.random.default_rng(1))
    assert not a["split"].equals(b["split"])
    with pytest.raises(ValueError, match="rally"):
        split_by_rally(table.drop(columns="rally"), np.random.default_rng(0))
    with pytest.raises(ValueError, match="fractions"):
        split_by_rally(table, np.random.default_rng(0), test_fraction=0.6, calibration_fraction=0.5)
