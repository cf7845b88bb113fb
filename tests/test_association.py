"""People matched across cameras by geometry, the scene as config, and the confidence-weighted DLT.

Synthetic projections of a rigid 8-joint body on a 3-camera twin rig (table frame, 480x360)."""

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pingpong.common.camera import Camera
from pingpong.frames import MODEL_JOINT_IDS
from pingpong.perception.pose3d import PoseSceneError, pose3d_table
from pingpong.perception.scene import Scene, default_players_scene
from pingpong.perception.schemas import MODEL_JOINT_COLUMNS, POSE2D
from pingpong.perception.triangulation import triangulate_dlt
from pingpong.twin.rig import make_rig

N_FRAMES = 40
# the 8 model joints about a standing person's mid-hip (m): shoulders, elbows, wrists, hips
BODY = np.array([[-0.2, 0, 0.5], [-0.3, 0, 0.25], [-0.3, 0.1, 0.0], [0.2, 0, 0.5], [0.3, 0, 0.25],
                 [0.3, 0.1, 0.0], [-0.1, 0, 0.0], [0.1, 0, 0.0]])
NEAR, FAR, BYSTANDER = np.array([0.2, 2.3, -0.1]), np.array([-0.3, -2.4, -0.1]), np.array([0.5, 3.4, -0.1])
SCENE = default_players_scene()


def _row(time_ns, person, px):
    return {"time_ns": time_ns, "person": person,
            **dict(zip(MODEL_JOINT_COLUMNS, np.column_stack([px, np.full(8, 0.9)]).ravel(), strict=True))}


def _tables(cameras, people, rng, noise_px=0.5):
    """POSE2D tables: people is a list of (3D centre, {camera: person id per frame or None}) entries."""
    tables = []
    for c, cam in enumerate(cameras):
        rows = []
        for f in range(N_FRAMES):
            time_ns = 10_000_000 * f
            here = [(ids[c][f], cam.project(centre + BODY)) for centre, ids in people
                    if c in ids and ids[c][f] is not None]
            rows += [_row(time_ns, pid, px + rng.normal(0, noise_px, px.shape)) for pid, px in here]
            if not here:
                rows.append(_row(time_ns, -1, np.full((8, 2), np.nan)))
        tables.append(pd.DataFrame(rows, columns=list(POSE2D.columns)).sort_values(["time_ns", "person"]))
    return tables


def _joints(pose, slot):
    rows = pose[pose["player"] == slot]
    return np.stack([rows[[f"j{j:02d}_{a}" for a in "xyz"]].to_numpy() for j in MODEL_JOINT_IDS], axis=1)


def _run(cameras, tables, scene=SCENE):
    return pose3d_table(cameras, tables, scene, 0.02, 0.005, 4.0, False, 2)


@pytest.fixture(scope="module")
def rig():
    return make_rig(np.random.default_rng(1), 3, 480, 360)


def test_a_bystander_seen_by_one_camera_is_never_used(rig):
    """The bystander stands 1.1 m behind the near player, inside the near area, seen by cam0 alone and
    listed there first (where in cam2 the two nearly overlap: a 2-view fit of cam0's bystander and cam2's
    player agrees, and loses to the player's 3 views)."""
    rng = np.random.default_rng(2)
    always = [0] * N_FRAMES
    people = [(NEAR, {0: [1] * N_FRAMES, 1: always, 2: always}), (FAR, {0: [2] * N_FRAMES, 1: [1] * N_FRAMES,
                                                                      2: [1] * N_FRAMES}),
              (BYSTANDER, {0: always})]
    pose, report = _run(rig, _tables(rig, people, rng))
    near = _joints(pose, "near")
    assert np.isfinite(near).all()
    assert np.abs(near - (NEAR + BODY)).max() < 0.03  # a view of the bystander would move joints by ~1 m
    kept = dict(zip(report["slots"], report["frames_kept"].T, strict=True))
    assert kept["near"].tolist() == [N_FRAMES] * 3
    assert np.abs(_joints(pose, "far") - (FAR + BODY)).max() < 0.03
    median, p90 = report["dlt_agreement_mm"]
    assert median < 2 and p90 < 5


def test_a_split_track_and_an_extra_detection_cost_no_frame(rig):
    """In cam1 the near player's tracklet splits (ids 0 then 5) with a duplicate detection at the split,
    1.2 m off in the image: every frame keeps its three views."""
    rng = np.random.default_rng(3)
    split = [0 if f < 20 else 5 for f in range(N_FRAMES)]
    duplicate = [4 if f == 20 else None for f in range(N_FRAMES)]
    people = [(NEAR, {0: [0] * N_FRAMES, 1: split, 2: [0] * N_FRAMES}),
              (NEAR + [1.2, 0.0, 0.0], {1: duplicate})]
    pose, report = _run(rig, _tables(rig, people, rng))
    assert report["frames_kept"][:, 0].tolist() == [N_FRAMES] * 3
    assert (pose.loc[pose["player"] == "near", "j02_n"] == 3).all()


def test_a_lab_frame_is_an_error_in_players_mode_and_found_in_subjects_mode(rig):
    """A subject at the lab's origin (between the player areas): 'players' finds nobody and says why,
    'subjects' finds the one subject."""
    rng = np.random.default_rng(4)
    tables = _tables(rig, [(np.array([0.0, 0.0, -0.1]), {c: [0] * N_FRAMES for c in range(3)})], rng)
    with pytest.raises(PoseSceneError, match="perception.scene.mode: subjects"):
        _run(rig, tables)
    pose, report = _run(rig, tables, Scene("subjects", 1, 1.5, (1.37, 4.37), 0.3))
    assert pose["player"].unique().tolist() == ["subject0"]
    assert np.abs(_joints(pose, "subject0") - BODY + [0, 0, 0.1]).max() < 0.03


def test_two_subjects_keep_their_labels(rig):
    rng = np.random.default_rng(5)
    a, b = np.array([-1.0, 0.0, -0.1]), np.array([1.0, 0.5, -0.1])
    swapped = [[0, 1][f % 2] for f in range(N_FRAMES)]  # the cameras list them in changing orders
    other = [[1, 0][f % 2] for f in range(N_FRAMES)]
    tables = _tables(rig, [(a, {c: swapped for c in range(3)}), (b, {c: other for c in range(3)})], rng)
    pose, _ = _run(rig, tables, Scene("subjects", 2, 1.5, (1.37, 4.37), 0.3))
    centres = [np.nanmean(_joints(pose, s), axis=1) for s in ("subject0", "subject1")]
    first = [np.argmin([np.linalg.norm(c[0] - p - [0, 0, 0.15]) for p in (a, b)]) for c in centres]
    assert sorted(first) == [0, 1]
    for c, k in zip(centres, first, strict=True):
        assert np.abs(c - ((a, b)[k] + BODY.mean(axis=0))).max() < 0.03  # every frame, the same person


def _cameras(seed):
    rng = np.random.default_rng(seed)
    return make_rig(rng, 4, 480, 360)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31), weights=st.lists(st.floats(0.05, 1.0), min_size=4, max_size=4),
       scale=st.floats(0.1, 10.0))
def test_weighted_dlt_exact_without_noise_and_scale_free(seed, weights, scale):
    """Noise-free views give the point for any positive weights; scaling all weights changes nothing;
    a zero weight is the view masked out."""
    cameras: list[Camera] = _cameras(seed % 7)
    rng = np.random.default_rng(seed)
    points = rng.uniform([-1, -2, 0], [1, 2, 1.5], (20, 3))
    P = np.stack([c.P for c in cameras])
    px = np.stack([(P[c] @ np.column_stack([points, np.ones(20)]).T).T for c in range(4)], axis=1)
    px = px[..., :2] / px[..., 2:]
    w = np.tile(weights, (20, 1))
    mask = np.ones((20, 4), bool)
    assert np.abs(triangulate_dlt(P, px, mask, w) - points).max() < 1e-6
    noisy = px + rng.normal(0, 1.0, px.shape)
    np.testing.assert_allclose(triangulate_dlt(P, noisy, mask, w * scale), triangulate_dlt(P, noisy, mask, w),
                               atol=1e-9)
    w[:, 1] = 0
    off = mask.copy()
    off[:, 1] = False
    zero, masked = triangulate_dlt(P, noisy, mask, w), triangulate_dlt(P, noisy, off, w)
    np.testing.assert_allclose(zero, masked, atol=1e-9)


def test_weights_pull_towards_the_confident_view():
    """One view 20 px off: weighting it down moves the point towards the others' agreement."""
    cameras = _cameras(3)
    P = np.stack([c.P for c in cameras])
    point = np.array([[0.2, 1.0, 0.8]])
    px = np.stack([c.project(point) for c in cameras], axis=1)
    bad = px.copy()
    bad[:, 0] += [20.0, 0.0]
    und = np.stack([c.undistort_pixels(bad[:, k]) for k, c in enumerate(cameras)], axis=1)
    mask = np.ones((1, 4), bool)
    even = np.linalg.norm(triangulate_dlt(P, und, mask) - point)
    weighted = np.linalg.norm(triangulate_dlt(P, und, mask, np.array([[0.1, 1, 1, 1]])) - point)
    assert weighted < 0.5 * even
