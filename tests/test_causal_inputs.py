"""The model's causal inputs end to end: through the real cleaning (the filtering rule's causal tables) and
the dataset's input sequences, a change to any measurement after frame t leaves every input up to t as it
was (and the zero-phase inputs, the control, do change); the streaming predictor fed the measurements
frame by frame gives the batch predictions on the dataset's inputs."""

import numpy as np
import pandas as pd
import pytest
from conftest import TINY_RUN
from workflow_util import DEFAULTS

from pingpong.common.artifacts import read_table
from pingpong.curation.causal import CausalLowpass, causal_session_inputs
from pingpong.curation.dataset import causal_input_cutoffs, input_sequences, player_frames
from pingpong.curation.filtering import filter_session
from pingpong.curation.labels import mirror_frames
from pingpong.curation.schemas import SEGMENTS
from pingpong.frames import FRAME_NS, N_INPUT
from pingpong.learning.models import load_net
from pingpong.learning.streaming import StreamingPredictor
from pingpong.learning.train import predict
from pingpong.perception.schemas import BALL3D, PADDLE, POSE3D

CURATION = {**DEFAULTS["curation"], **TINY_RUN.get("curation", {})}
CUTOFFS = causal_input_cutoffs(CURATION["causal_cutoff_pose_hz"], CURATION["causal_cutoff_ball_hz"])


@pytest.fixture(scope="module")
def session(tiny_run):
    """The tiny run's first session: raw 3D tables, paddle, its kept candidates."""
    name = sorted(p.stem for p in (tiny_run / "interim/ball3d").glob("*.parquet"))[0]
    tables = (read_table(tiny_run / f"interim/ball3d/{name}.parquet", BALL3D),
              read_table(tiny_run / f"interim/pose3d/{name}.parquet", POSE3D),
              read_table(tiny_run / f"interim/paddle/{name}.parquet", PADDLE))
    segments = read_table(tiny_run / f"interim/segments/{name}.parquet", SEGMENTS)
    kept = segments[segments["decision"] == "kept"].sort_values("hit_frame").reset_index(drop=True)
    assert len(kept) >= 3
    return tables, kept


def causal_inputs(ball3d, pose3d, paddle, kept):
    ball, pose = causal_session_inputs(ball3d, pose3d, cutoff_ball_hz=None, cutoff_pose_hz=None)
    return input_sequences(kept, ball, pose, paddle, causal_cutoffs=CUTOFFS)[0]


def zero_phase_inputs(ball3d, pose3d, paddle, kept):
    cutoffs = CURATION["cutoff_ball_hz"], CURATION["cutoff_pose_hz"]
    ball, pose, _ = filter_session(ball3d, pose3d, paddle, *cutoffs)
    return input_sequences(kept, ball, pose, paddle)[0]


def after(table: pd.DataFrame, cut_ns: int) -> np.ndarray:
    return (table["time_ns"] > cut_ns).to_numpy()


def perturbed(tables, cut_ns: int, rng: np.random.Generator):
    """Every measurement after cut_ns moved (ball, joints, paddle) and some of them lost."""
    ball3d, pose3d, paddle = (t.copy() for t in tables)
    late = after(ball3d, cut_ns)
    ball3d.loc[late, ["x", "y", "z"]] += rng.normal(0, 0.3, (late.sum(), 3))
    ball3d.loc[late & (rng.random(len(ball3d)) < 0.2), ["x", "y", "z"]] = np.nan
    late = after(pose3d, cut_ns)
    joints = [c for c in pose3d.columns if c.endswith(("_x", "_y", "_z"))]  # POSE3D names its keypoints
    assert joints
    pose3d.loc[late, joints] += rng.normal(0, 0.2, (late.sum(), len(joints)))
    late = after(paddle, cut_ns)
    paddle.loc[late, ["px", "py", "pz"]] += rng.normal(0, 0.2, (late.sum(), 3))
    return ball3d, pose3d, paddle


@pytest.mark.parametrize("frames_before_hit", [0, 5, 20])
def test_no_input_at_t_depends_on_a_measurement_after_t(session, frames_before_hit):
    tables, kept = session
    hit = kept.iloc[len(kept) // 2]
    cut_ns = int(hit["t_hit_ns"]) - frames_before_hit * FRAME_NS  # t: the hit frame's clock minus k frames
    ball_ns = tables[0].sort_values("time_ns")["time_ns"].to_numpy()
    rng = np.random.default_rng(frames_before_hit)
    base = causal_inputs(*tables, kept)
    moved = causal_inputs(*perturbed(tables, cut_ns, rng), kept)
    n_frames = base.shape[1]
    for k, seg in kept.iterrows():
        window_ns = ball_ns[seg["hit_frame"] - n_frames + 1:seg["hit_frame"] + 1]
        up_to_t = window_ns <= cut_ns
        np.testing.assert_array_equal(moved[k, up_to_t], base[k, up_to_t])
    later = kept.index[kept["hit_frame"] > hit["hit_frame"] + 5]
    assert not np.array_equal(moved[later], base[later])  # the perturbation did reach the later inputs
    # the control: zero-phase inputs up to t do move (the filter carries later measurements back)
    zero = zero_phase_inputs(*tables, kept)
    zero_moved = zero_phase_inputs(*perturbed(tables, cut_ns, np.random.default_rng(frames_before_hit)), kept)
    k = kept.index[kept["hit"] == hit["hit"]][0]
    window_ns = ball_ns[hit["hit_frame"] - n_frames + 1:hit["hit_frame"] + 1]
    assert not np.array_equal(zero_moved[k, window_ns <= cut_ns], zero[k, window_ns <= cut_ns])


def test_streaming_on_measurements_equals_the_batch_prediction(session, tiny_run):
    tables, kept = session
    net = load_net(str(tiny_run / "processed/models/final/seed0"))
    X = causal_inputs(*tables, kept)
    ball, pose = causal_session_inputs(tables[0], tables[1], cutoff_ball_hz=None, cutoff_pose_hz=None)
    n_frames = X.shape[1]
    checked = 0
    for k, seg in kept.iterrows():
        measured = player_frames(ball, pose, tables[2], seg["hitter"])
        first = seg["hit_frame"] - n_frames + 1
        if not np.isfinite(measured[:first]).any(axis=0).all():
            continue  # a value never seen before the window: the dataset's one non-causal fill
        if seg["hitter"] == "far":
            measured = mirror_frames(measured)
        stream = StreamingPredictor(net, CausalLowpass(N_INPUT, CUTOFFS))
        for frame in measured[:first]:  # the filter runs from the session's start
            stream.observe(frame)
        stream.reset()
        streamed = np.array([stream.step(frame)[0] for frame in measured[first:seg["hit_frame"] + 1]])
        batch = predict(net, X[k:k + 1])[0]  # (31, 3) at t = -30 .. 0
        np.testing.assert_allclose(streamed[-batch.shape[0]:], batch, atol=1e-5)
        checked += 1
    assert checked >= 2
