"""People matched across cameras by geometry, the scene as config, and the confidence-weighted DLT.

Synthetic projections of a rigid 8-joint body on a 3-camera twin rig (table frame, 480x360), and the
tiny run's OpenPose people against its truth."""

import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from pingpong.common.camera import Camera
from pingpong.frames import MODEL_JOINT_IDS, MODEL_JOINTS
from pingpong.perception.association import _median_error, associate, people_arrays
from pingpong.perception.calibration import load_cameras
from pingpong.perception.pose2d import pose2d_table
from pingpong.perception.pose3d import PoseSceneError, pose3d_table
from pingpong.perception.scene import Scene, default_players_scene
from pingpong.perception.schemas import MODEL_JOINT_COLUMNS, POSE2D
from pingpong.perception.triangulation import reprojection_gate_px, triangulate_dlt
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
    """POSE2D tables: people is a list of (3D centre (3,) or per joint (8, 3) added to BODY, {camera:
    person id per frame or None}) entries."""
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
    return np.stack([rows[[f"{j}_{a}" for a in "xyz"]].to_numpy() for j in MODEL_JOINTS], axis=1)


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


def test_a_bystander_overlapping_the_player_where_a_camera_misses_him_is_never_used(rig):
    """The open tie of geometry: cam1 misses the near player in 10 frames; a bystander seen by cam0 alone
    stands 1.1 m behind the player on cam2's rays (projecting onto the player there), so cam0's bystander
    and cam2's player agree exactly as well as the player's own two views. The bystander's cam0 tracklet
    was seen beside the player's in the other 30 frames: the player's views win every frame."""
    rng = np.random.default_rng(6)
    reach = NEAR + BODY - rig[2].center
    behind = rig[2].center + reach * (1 + 1.1 / np.linalg.norm(reach.mean(axis=0)))  # (8, 3)
    seen_by_cam1 = [0 if f % 4 else None for f in range(N_FRAMES)]
    always = [0] * N_FRAMES
    people = [(NEAR, {0: always, 1: seen_by_cam1, 2: always}),
              (FAR, {c: [2] * N_FRAMES for c in range(3)}),
              (behind - BODY, {0: [1] * N_FRAMES})]  # its own joints: a taller person
    tables = _tables(rig, people, rng)
    np.testing.assert_allclose(rig[2].project(behind), rig[2].project(NEAR + BODY), atol=1e-6)
    times = tables[0]["time_ns"].unique()
    choice = associate(rig, [people_arrays(t, times) for t in tables], SCENE, reprojection_gate_px(rig, 0.02))
    cam0 = people_arrays(tables[0], times)[2]
    assert (cam0[np.arange(N_FRAMES), choice[:, 0, 0]] == 0).all()  # cam0 gives near the player's tracklet
    pose, _ = _run(rig, tables)
    assert np.abs(_joints(pose, "near") - (NEAR + BODY)).max() < 0.03  # the bystander's view: ~1 m off


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
    assert (pose.loc[pose["player"] == "near", "RShoulder_views"] == 3).all()


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


@settings(max_examples=200, deadline=None)
@given(errors=arrays(float, st.tuples(st.integers(1, 4), st.integers(1, 9), st.integers(1, 3)),
                     elements=st.one_of(st.floats(0, 100), st.just(np.nan))))
def test_median_error_is_the_median_of_the_finite_errors(errors):
    """Per point and view, the median over joints of the finite errors (inf where none) and their count."""
    median, count = _median_error(errors)
    np.testing.assert_array_equal(count, np.isfinite(errors).sum(axis=1))
    for p, v in np.ndindex(median.shape):
        finite = errors[p, :, v][np.isfinite(errors[p, :, v])]
        assert median[p, v] == (np.median(finite) if len(finite) else np.inf)


def _tiny_identity(px, truth_px):
    """(F, P) index (near, far, bystander) of the truth person whose projected model joints are nearest
    each person's (median over the joints seen); -1 where a person has none. px (F, P, J, 2),
    truth_px (F, 3, J, 2), NaN where absent."""
    dist = np.linalg.norm(px[:, :, None] - truth_px[:, None], axis=-1)  # (F, P, 3, J)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN slices: nobody there
        median = np.nanmedian(dist, axis=-1)
    ids = np.argmin(np.nan_to_num(median, nan=np.inf), axis=-1)
    return np.where(np.isfinite(px[..., 0]).any(axis=-1), ids, -1)


def test_the_choice_per_camera_and_player_matches_the_truth(tiny_run):
    """The tiny run's OpenPose people (pose2d with this checkout's code, from raw/) matched across its
    cameras: per camera and player, over the frames where the camera and at least one other detect the
    player, the camera gives the player's slot his own detection in >= 95 % of them, else none (with a
    detector's errors a view with a swapped limb or joints hidden behind the trunk disagrees now and then:
    1.1 % of cam2's far player on the tiny run at swap_rate 0.01; at 0.045, the rate after PoseFix's
    inversions that issue 41 set, 0.9-4.1 % by camera and player, cam2's far player the most; the bar was 97 %
    before); no camera ever gives a slot the bystander or the other
    player; the chosen joints lie as near the truth as the twin's detector puts them (COCO's sigmas of
    the person's scale: a median within 6 px at 480 px width)."""
    root = Path(tiny_run)
    cameras, _ = load_cameras(root / "interim/calibration/cameras.json")
    truth = pd.read_parquet(root / "raw/twin_truth/s00/people.parquet")
    names = ("near", "far", "bystander")
    bodies = np.stack([truth[truth["person"] == n].sort_values("time_ns")[
        [f"j{j:02d}_{a}" for j in MODEL_JOINT_IDS for a in "xyz"]].to_numpy().reshape(-1, 8, 3)
        for n in names], axis=1)  # (F, 3, 8, 3)
    times = np.sort(truth["time_ns"].unique())
    people, who = [], []
    for cam in cameras:
        clock = pd.read_parquet(root / f"interim/pose2d/s00/{cam.name}.parquet", columns=["time_ns"])
        np.testing.assert_array_equal(clock["time_ns"].unique(), times)
        table = pose2d_table(root / f"raw/sessions/s00/openpose/{cam.name}", times)
        people.append(people_arrays(table, times))
        truth_px = cam.project(np.nan_to_num(bodies).reshape(-1, 3)).reshape(*bodies.shape[:3], 2)
        truth_px[np.isnan(bodies).any(axis=-1)] = np.nan
        who.append((_tiny_identity(people[-1][0], truth_px), truth_px))
    choice = associate(cameras, people, SCENE, reprojection_gate_px(cameras, 0.02))
    detected = np.stack([(w[..., None] == np.arange(3)).any(axis=1) for w, _ in who], axis=-1)  # (F, 3, C)
    assert detected[:, 2].any(axis=-1).sum() > 100  # the test saw the bystander
    frames = np.arange(len(times))[:, None]
    errors = []
    for c, (w, truth_px) in enumerate(who):
        assert (detected[:, 0, c] & detected[:, 1, c]).mean() > 0.9
        chosen_as = np.where(choice[..., c] >= 0, w[frames, np.maximum(choice[..., c], 0)], -1)  # (F, 2)
        assert not (chosen_as == 2).any(), f"{cameras[c].name}: the bystander was chosen"
        for side in range(2):
            mask = detected[:, side, c] & (detected[:, side].sum(axis=-1) >= 2)
            accuracy = np.mean(chosen_as[mask, side] == side)
            assert accuracy >= 0.95, f"{cameras[c].name} {names[side]}: {accuracy:.4f} of frames chosen right"
            assert not (chosen_as[:, side] == 1 - side).any(), f"{cameras[c].name}: the players mixed up"
            f = np.flatnonzero(chosen_as[:, side] == side)
            errors.append(np.linalg.norm(people[c][0][f, choice[f, side, c]] - truth_px[f, side], axis=-1))
    errors = np.concatenate(errors, axis=None)
    assert np.nanmedian(errors) < 6.0
