"""Causal inputs: forward low-pass (batch and streaming), past-only ball gate, trailing pose check and
the causal session tables; causality is checked as a property (changing the future leaves the past)."""

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import butter, sosfilt, sosfilt_zi

from pingpong.curation.causal import CausalLowpass, causal_lowpass, causal_session_inputs
from pingpong.curation.events import drop_ball_outliers
from pingpong.curation.filtering import clean_pose, filter_session
from pingpong.curation.tracks import JOINT_VIEWS, JOINT_XYZ
from pingpong.frames import FRAME_NS, ROT_COLUMNS

FS = 100.0
CUTOFFS = st.sampled_from([None, 4.0, 15.0, 30.0])
EPOCH = 1_700_000_000 * 10**9


def _same(a, b, atol=0.0):
    np.testing.assert_allclose(a, b, rtol=0, atol=atol, equal_nan=True)


@st.composite
def signals(draw, max_frames=80, max_channels=4):
    """(values (T, D) with NaN, a frame t, the same values changed after t, values and NaN alike)."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    n, d = draw(st.integers(1, max_frames)), draw(st.integers(1, max_channels))
    nan_share = draw(st.sampled_from([0.0, 0.2, 0.6, 1.0]))
    values = np.cumsum(rng.normal(0, 1, (n, d)), axis=0)
    values[rng.random((n, d)) < nan_share] = np.nan
    t = draw(st.integers(0, n - 1))
    future = values.copy()
    future[t + 1:] = rng.normal(0, 5, (n - t - 1, d))
    future[t + 1:][rng.random((n - t - 1, d)) < draw(st.sampled_from([0.0, 0.5, 1.0]))] = np.nan
    return values, t, future


# --- causal_lowpass / CausalLowpass


@settings(max_examples=150)
@given(signals(), st.data())
def test_lowpass_is_causal(case, data):
    values, t, future = case
    cutoffs = data.draw(st.lists(CUTOFFS, min_size=values.shape[1], max_size=values.shape[1]))
    _same(causal_lowpass(future, cutoffs)[:t + 1], causal_lowpass(values, cutoffs)[:t + 1])


@settings(max_examples=100)
@given(signals(), st.data(), st.sampled_from([1, 2, 4]))
def test_streaming_equals_batch(case, data, order):
    values = case[0]
    cutoffs = data.draw(st.lists(CUTOFFS, min_size=values.shape[1], max_size=values.shape[1]))
    stream = CausalLowpass(values.shape[1], cutoffs, FS, order)
    streamed = np.array([stream.step(row) for row in values])
    _same(streamed, causal_lowpass(values, cutoffs, FS, order), atol=1e-12)
    stream.reset()
    _same(np.array([stream.step(row) for row in values]), streamed)


def test_nan_free_column_is_scipy_forward_filter_from_steady_state():
    x = np.cumsum(np.random.default_rng(0).normal(0, 0.01, 500)) + 1.3
    for order, cutoff in ((1, 8.0), (2, 15.0), (4, 25.0)):
        sos = butter(order, cutoff, fs=FS, output="sos")
        expected = sosfilt(sos, x, zi=sosfilt_zi(sos) * x[0])[0]
        _same(causal_lowpass(x, cutoff, FS, order), expected, atol=1e-15)


def test_constant_passes_unchanged_through_gaps():
    x = np.full((300, 3), [0.5, -1.2, 2.0])
    x[:20, 1] = x[100:140, :] = x[250, 2] = np.nan
    out = causal_lowpass(x, [8.0, 15.0, None])
    assert (np.isnan(out) == np.isnan(x)).all()
    _same(out, x, atol=1e-14)


def test_step_settles_to_the_step_and_does_not_start_early():
    x = np.r_[np.zeros(50), np.ones(250)]
    for order in (1, 2, 4):
        out = causal_lowpass(x, 8.0, FS, order)
        assert (out[:50] == 0).all()
        assert abs(out[-1] - 1) < 1e-9


def test_gap_outputs_nan_while_the_filter_runs_on_the_held_value():
    rng = np.random.default_rng(1)
    x = np.cumsum(rng.normal(0, 0.02, 200))
    gappy = x.copy()
    gappy[:10] = gappy[60:90] = np.nan
    out = causal_lowpass(gappy, 10.0)
    held = pd.Series(gappy[10:]).ffill().to_numpy()
    expected = causal_lowpass(held, 10.0)
    assert np.isnan(out[:10]).all() and np.isnan(out[60:90]).all()
    finite = np.isfinite(gappy[10:])
    _same(out[10:][finite], expected[finite])


def test_unfiltered_channel_and_bad_settings():
    x = np.random.default_rng(2).normal(size=(50, 2))
    x[5, 0] = np.nan
    _same(causal_lowpass(x, [None, 10.0])[:, 0], x[:, 0])
    with pytest.raises(ValueError):
        causal_lowpass(x, 50.0)  # Nyquist
    with pytest.raises(ValueError):
        causal_lowpass(x, [10.0])
    with pytest.raises(ValueError):
        CausalLowpass(2, 10.0).step(np.zeros(3))


# --- ball gate


def _ball3d(xyz) -> pd.DataFrame:
    seen = np.isfinite(xyz).all(axis=1)
    return pd.DataFrame({"time_ns": EPOCH + FRAME_NS * np.arange(len(xyz)),
                         **{a: xyz[:, k] for k, a in enumerate("xyz")},
                         "n_views": np.where(seen, 3, 0), "reproj_rms_px": np.where(seen, 0.5, np.nan)})


def _flight(rng, n, outliers=0.05, nan_share=0.1):
    xyz = np.cumsum(rng.normal(0, 0.05, (n, 3)), axis=0)
    thrown = rng.random(n) < outliers
    xyz[thrown] += rng.uniform(0.5, 2.0, (thrown.sum(), 3))
    xyz[rng.random(n) < nan_share] = np.nan
    return xyz


@settings(max_examples=100)
@given(st.integers(0, 2**32 - 1), st.integers(1, 80), st.data())
def test_ball_gate_is_causal(seed, n, data):
    rng = np.random.default_rng(seed)
    xyz = _flight(rng, n)
    t = data.draw(st.integers(0, n - 1))
    future = xyz.copy()
    future[t + 1:] = _flight(rng, n - t - 1, outliers=0.3, nan_share=0.4)
    past = drop_ball_outliers(_ball3d(xyz), causal=True).iloc[:t + 1]
    pd.testing.assert_frame_equal(drop_ball_outliers(_ball3d(future), causal=True).iloc[:t + 1], past)


def test_ball_gate_past_only_drops_the_first_sample_after_a_gap():
    xyz = np.column_stack([np.linspace(0, 1, 20), np.zeros(20), np.full(20, 0.3)])
    xyz[5:10] = np.nan
    xyz[15] += 1.0  # thrown: metres off its flight
    offline, live = (drop_ball_outliers(_ball3d(xyz), causal=c) for c in (False, True))
    assert np.isnan(offline.loc[15, "x"]) and np.isnan(live.loc[15, "x"]) and live.loc[15, "n_views"] == 0
    assert np.isfinite(offline.loc[[0, 10], "x"]).all()  # confirmed by the samples after them
    assert np.isnan(live.loc[[0, 10], "x"]).all()  # nothing before them to confirm
    assert np.isfinite(live.loc[[1, 11, 16], "x"]).all()  # 16: confirmed by 14, two frames back
    assert np.isfinite(offline.drop(index=[15])[["x", "y", "z"]].to_numpy()[[0, 1, 10, 11, 16]]).all()


# --- pose check


def _pose3d(rng, n, players=("near", "far"), thrown=0.02, nan_share=0.02) -> pd.DataFrame:
    parts = []
    for k, player in enumerate(players):
        skeleton = np.tile(rng.normal(0, 0.3, len(JOINT_XYZ)) + k, (n, 1))
        joints = skeleton + rng.normal(0, 0.01, skeleton.shape)
        joints[rng.random(joints.shape) < thrown] += 0.4
        joints[rng.random(joints.shape) < nan_share] = np.nan
        table = pd.DataFrame(joints, columns=JOINT_XYZ).assign(player=player,
                                                                time_ns=EPOCH + FRAME_NS * np.arange(n))
        for j, views in enumerate(JOINT_VIEWS):
            table[views] = np.where(np.isfinite(joints[:, 3 * j]), 3, 0)
        parts.append(table)
    columns = ["time_ns", "player", *[c for j in range(len(JOINT_VIEWS)) for c in
                                      (*JOINT_XYZ[3 * j:3 * j + 3], JOINT_VIEWS[j])]]
    return pd.concat(parts).sort_values(["time_ns", "player"], kind="stable").reset_index(drop=True)[columns]


def _changed_after(table: pd.DataFrame, t_ns: int, rng) -> pd.DataFrame:
    out = table.copy()
    later = (out["time_ns"] > t_ns).to_numpy()
    values = out.loc[later, JOINT_XYZ].to_numpy(float) + rng.normal(0, 0.5, (later.sum(), len(JOINT_XYZ)))
    values[rng.random(values.shape) < 0.3] = np.nan
    out.loc[later, JOINT_XYZ] = values
    return out


@settings(max_examples=60)
@given(st.integers(0, 2**32 - 1), st.integers(1, 60), st.data())
def test_pose_check_is_causal(seed, n, data):
    rng = np.random.default_rng(seed)
    pose = _pose3d(rng, n)
    t_ns = EPOCH + FRAME_NS * data.draw(st.integers(0, n - 1))
    future = _changed_after(pose, t_ns, rng)
    past = pose["time_ns"] <= t_ns
    pd.testing.assert_frame_equal(clean_pose(future, causal=True, window_s=0.2)[past],
                                  clean_pose(pose, causal=True, window_s=0.2)[past])


def test_pose_check_reference_trails_offline_uses_the_session():
    """A forearm 0.25 m for 20 s then 0.40 m for 10 s: offline, the session median (0.25) removes the wrist
    in the last 10 s; causal, the 10 s trailing median removes it only until it has turned (5 s)."""
    n = 3000
    pose = _pose3d(np.random.default_rng(3), n, players=("near",), thrown=0.0, nan_share=0.0)
    elbow, wrist = JOINT_XYZ[3:6], JOINT_XYZ[6:9]
    pose[wrist] = pose[elbow].to_numpy() + np.where(np.arange(n)[:, None] < 2000, 0.25, 0.40) * [1, 0, 0]
    pose.loc[500, wrist] = pose.loc[500, elbow].to_numpy() + [0.6, 0, 0]  # thrown, on one frame
    gone = {c: np.isnan(clean_pose(pose, causal=c)[wrist[0]]).to_numpy() for c in (False, True)}
    assert gone[False][500] and gone[True][500]
    assert gone[False][2000:].all() and gone[False][:2000].sum() == 1
    assert gone[True][2000:2490].all() and not gone[True][2510:].any() and gone[True][:2000].sum() == 1
    assert not np.isnan(clean_pose(pose, causal=True)[elbow[0]]).any()  # the upper arm vouches for it


@pytest.mark.parametrize("causal", [False, True])
def test_pose_check_tolerates_a_detectors_noise_and_still_throws_out_wrong_joints(causal):
    """Joints with 3.5 cm of noise per axis (a detector's, as on the harder twin): a bone's length
    scatters by several cm, past the fixed 10 cm now and then; the tolerance grows with that scatter, so
    almost no frame is lost to noise while a joint thrown 0.6 m (onto another arm or person) still is."""
    n = 3000
    rng = np.random.default_rng(11)
    pose = _pose3d(rng, n, players=("near",), thrown=0.0, nan_share=0.0)
    pose[JOINT_XYZ] += rng.normal(0, 0.035, (n, len(JOINT_XYZ)))
    thrown = rng.choice(n, 30, replace=False)
    wrist = JOINT_XYZ[6:9]
    pose.loc[thrown, wrist] += [0.6, 0, 0]
    gone = np.isnan(clean_pose(pose, causal=causal)[wrist[0]]).to_numpy()
    others = np.setdiff1d(np.arange(n), thrown)
    assert gone[thrown[thrown > 100]].all()  # causal: a reference needs a few frames first
    assert gone[others].mean() < 0.01
    forearm = np.linalg.norm(pose[wrist].to_numpy() - pose[JOINT_XYZ[3:6]].to_numpy(), axis=1)
    assert (np.abs(forearm - np.median(forearm))[others] > 0.10).mean() > 0.02  # noise past a fixed 10 cm


# --- session tables


def _paddle(time_ns) -> pd.DataFrame:
    """An OptiTrack table that lost both paddles: events need one, these tests do not."""
    rows = {"time_ns": np.repeat(time_ns, 2), "player": np.tile(["near", "far"], len(time_ns))}
    values = {c: np.nan for c in ("px", "py", "pz", *ROT_COLUMNS)}
    return pd.DataFrame({**rows, **values, "valid": False})


def test_session_tables_have_filter_sessions_layout():
    rng = np.random.default_rng(4)
    ball3d, pose3d = _ball3d(_flight(rng, 400)).sample(frac=1, random_state=0), _pose3d(rng, 400)
    pose3d = pose3d.sample(frac=1, random_state=1)  # any row order in, the same order out
    offline = filter_session(ball3d, pose3d, _paddle(ball3d["time_ns"].sort_values()), 15.0, 8.0)
    live = causal_session_inputs(ball3d, pose3d, 15.0, 8.0)
    for table, off, keys in zip(live, offline[:2], (["time_ns"], ["time_ns", "player"]), strict=True):
        assert list(table.columns) == list(off.columns) and table.dtypes.equals(off.dtypes)
        pd.testing.assert_frame_equal(table[keys], off[keys])


def test_session_tables_keep_gaps_and_pass_unfiltered():
    rng = np.random.default_rng(5)
    ball3d, pose3d = _ball3d(_flight(rng, 300)), _pose3d(rng, 300)
    ball, pose = causal_session_inputs(ball3d, pose3d, None, None)
    gated = drop_ball_outliers(ball3d, causal=True)
    pd.testing.assert_frame_equal(ball, gated)
    pd.testing.assert_frame_equal(pose, clean_pose(pose3d, causal=True))
    ball, pose = causal_session_inputs(ball3d, pose3d, 15.0, 8.0)
    assert (np.isnan(ball[["x", "y", "z"]]) == np.isnan(gated[["x", "y", "z"]])).all().all()
    checked = clean_pose(pose3d, causal=True)
    assert (np.isnan(pose[JOINT_XYZ]) == np.isnan(checked[JOINT_XYZ])).all().all()


@settings(max_examples=40)
@given(st.integers(0, 2**32 - 1), st.integers(1, 60), st.data(), st.sampled_from([None, 15.0]))
def test_session_tables_are_causal(seed, n, data, cutoff_ball):
    rng = np.random.default_rng(seed)
    ball3d, pose3d = _ball3d(_flight(rng, n)), _pose3d(rng, n)
    t = data.draw(st.integers(0, n - 1))
    t_ns = EPOCH + FRAME_NS * t
    later_ball = ball3d.copy()
    later_ball.loc[t + 1:, ["x", "y", "z"]] = _flight(rng, n - t - 1, outliers=0.3, nan_share=0.4)
    live = causal_session_inputs(ball3d, pose3d, cutoff_ball, 8.0)
    changed = causal_session_inputs(later_ball, _changed_after(pose3d, t_ns, rng), cutoff_ball, 8.0)
    for a, b in zip(live, changed, strict=True):
        past = (a["time_ns"] <= t_ns).to_numpy()
        pd.testing.assert_frame_equal(a[past], b[past])
