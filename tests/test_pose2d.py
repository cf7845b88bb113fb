"""2D poses: OpenPose people assigned to the near/far players, checked against the twin's truth.

The data are simulated here (a short session, a 2-camera rig at 480x360, OpenPose's errors per
frame), so CI needs no recordings. A detection's identity is the truth person whose projected
joints are nearest (median over its detected joints).
"""

import itertools
import json
import warnings

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from pingpong.common.artifacts import Provenance, read_table, write_table
from pingpong.frames import BODY25, MODEL_JOINT_IDS
from pingpong.io.openpose_json import BODY25_NAME, KEYPOINT_MODELS, write_keypoints_json
from pingpong.perception.pose2d import (
    MIN_CONFIDENCE,
    TYPICAL_HEIGHTS,
    assign_sides,
    best_tracklets,
    fix_limb_swaps,
    floor_positions,
    model_joints,
    pose2d_table,
)
from pingpong.perception.schemas import POSE2D
from pingpong.twin.openpose_sim import LIMB_SWAPS, simulate_openpose
from pingpong.twin.players import bystander_joints
from pingpong.twin.rig import make_rig
from pingpong.twin.session import FaultRates, simulate_session
from pingpong.twin.truth import JOINT_COLUMNS

PEOPLE = ("near", "far", "bystander")


def _openpose(camera, bodies, rng, swap_rate=0.01):
    """(F, P, 25, 3) simulated OpenPose people of every frame of bodies (F, 3, 25, 3), zero-padded."""
    frames = [simulate_openpose(camera, [b for b in bodies[f] if not np.isnan(b).all()], rng, swap_rate)
              for f in range(len(bodies))]
    out = np.zeros((len(frames), max(map(len, frames)), 25, 3))
    for f, people in enumerate(frames):
        out[f, :len(people)] = people
    return out


def _projected(camera, bodies):
    """(F, 3, 25, 2) projected true joints; NaN where a person is absent."""
    px = camera.project(np.nan_to_num(bodies).reshape(-1, 3)).reshape(*bodies.shape[:3], 2)
    px[np.isnan(bodies).any(axis=-1)] = np.nan
    return px


def _identity(people, truth_px):
    """(F, P) index into PEOPLE of the truth person nearest to each detection; -1 where none."""
    detected = people[..., 2] > 0
    dist = np.linalg.norm(people[:, :, None, :, :2] - truth_px[:, None], axis=-1)  # (F, P, 3, 25)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        median = np.nanmedian(np.where(detected[:, :, None], dist, np.nan), axis=-1)
    ids = np.argmin(np.nan_to_num(median, nan=np.inf), axis=-1)
    return np.where(detected.any(axis=-1), ids, -1)


@pytest.fixture(scope="module")
def twin():
    """A 2-rally session with a bystander half of the time, a 2-camera rig and OpenPose per camera."""
    rng = np.random.default_rng(11)
    truth = simulate_session(2, FaultRates(), rng, bystander_rate=0.5)
    people = truth.people
    bodies = np.stack([people[people.person == p][list(JOINT_COLUMNS)].to_numpy().reshape(-1, 25, 3)
                       for p in PEOPLE], axis=1)  # (F, 3, 25, 3)
    cameras = make_rig(rng, 2, 480, 360)
    keypoints = [_openpose(camera, bodies, rng) for camera in cameras]
    return bodies, cameras, keypoints, rng


def _check_assignment(sides, keypoints, truth_px, min_accuracy=0.99):
    detected_as = _identity(keypoints, truth_px)
    assigned_as = _identity(sides, truth_px)
    for side in range(2):
        detected = (detected_as == side).any(axis=1)
        accuracy = np.mean(assigned_as[detected, side] == side)
        assert accuracy >= min_accuracy, f"{PEOPLE[side]}: {accuracy:.4f} of frames assigned right"
        assert not (assigned_as[:, side] == 2).any(), "a bystander was assigned to a player"
    return detected_as, assigned_as


def test_sides_match_the_truth(twin):
    """>= 99 % of frames right where the player is detected, bystanders never, median error < 3 px."""
    bodies, cameras, keypoints, _ = twin
    bystander_frames = 0
    for camera, people in zip(cameras, keypoints, strict=True):
        truth_px = _projected(camera, bodies)
        sides = assign_sides(people, camera)
        detected_as, _ = _check_assignment(sides, people, truth_px)
        assert ((detected_as == 0).any(axis=1) & (detected_as == 1).any(axis=1)).mean() > 0.9
        bystander_frames += (detected_as == 2).any(axis=1).sum()
        joints = model_joints(fix_limb_swaps(sides))
        errors = np.linalg.norm(joints[..., :2] - truth_px[:, :2][:, :, list(MODEL_JOINT_IDS)], axis=-1)
        errors = errors[np.isfinite(errors)]
        assert len(errors) > 0.5 * joints[..., 0].size
        assert np.median(errors) < 3.0  # measured ~1.3 px (OpenPose noise 1 px at 480 px width)
    assert bystander_frames > 100  # the test saw a bystander


def test_bystander_at_the_table_corner_while_the_player_is_unseen(twin):
    """A bystander just beside the near end is never taken for the near player, even in the 0.3 s
    stretches in which the near player is not detected at all."""
    bodies, cameras, _, rng = twin
    bodies = bodies[:450].copy()
    bystander = bystander_joints(np.arange(len(bodies)) / 100, rng)  # in the room all the time
    bodies[:, 2] = bystander + np.array([1.6, 1.3, 0.0]) - bystander[:, 8].mean(axis=0) * [1, 1, 0]
    for start in range(100, len(bodies), 200):
        bodies[start:start + 30, 0] = np.nan
    for camera in cameras:
        people = _openpose(camera, bodies, rng)
        _check_assignment(assign_sides(people, camera), people, _projected(camera, bodies))


def test_person_order_and_padding_do_not_matter(twin):
    bodies, cameras, keypoints, _ = twin
    camera, people = cameras[0], keypoints[0][:300]
    rng = np.random.default_rng(3)
    shuffled = np.concatenate([people, np.zeros((len(people), 2, 25, 3))], axis=1)
    shuffled = np.stack([frame[rng.permutation(len(frame))] for frame in shuffled])
    np.testing.assert_array_equal(assign_sides(shuffled, camera), assign_sides(people, camera))


def test_missing_people_and_empty_frames(twin):
    bodies, cameras, keypoints, _ = twin
    camera, people = cameras[1], keypoints[1][:300].copy()
    truth_px = _projected(camera, bodies[:300])
    ids = _identity(people, truth_px)
    people[100:150] = 0  # nobody detected
    people[200:260][ids[200:260] == 1] = 0  # the far player missed
    sides = assign_sides(people, camera)
    assert (sides[100:150] == 0).all() and (sides[200:260, 1] == 0).all()
    _check_assignment(sides, people, truth_px, min_accuracy=1.0)
    assert (assign_sides(np.zeros((5, 0, 25, 3)), camera) == 0).all()
    assert (assign_sides(np.zeros((5, 3, 25, 3)), camera) == 0).all()


def test_limb_swaps_are_undone(twin):
    """Single-frame swaps of an arm, leg or foot (here in 5 % of frames) are undone from 2D continuity:
    at least 90 % of the swapped limbs (all joints seen and nearer the other side's truth)."""
    bodies, cameras, _, rng = twin
    camera, bodies = cameras[1], bodies[:400]
    people = _openpose(camera, bodies, rng, swap_rate=0.05)
    truth_px = _projected(camera, bodies)[:, :2]

    def swapped(sides):
        count = 0
        for right, left in LIMB_SWAPS:
            both = list(right + left)
            mirrored = list(left + right)
            seen = (sides[:, :, both, 2] > 0).all(axis=-1)
            straight = np.linalg.norm(sides[:, :, both, :2] - truth_px[:, :, both], axis=-1).sum(axis=-1)
            crossed = np.linalg.norm(sides[:, :, both, :2] - truth_px[:, :, mirrored], axis=-1).sum(axis=-1)
            count += np.sum(seen & (crossed < straight))
        return count

    sides = assign_sides(people, camera)
    before, after = swapped(sides), swapped(fix_limb_swaps(sides))
    assert before >= 10 and after <= 0.1 * before, (before, after)


def test_low_confidence_joints_become_gaps():
    players = np.zeros((2, 2, 25, 3))
    players[..., 0], players[..., 1], players[..., 2] = 100.0, 50.0, 0.9
    players[0, 0, MODEL_JOINT_IDS[2], 2] = MIN_CONFIDENCE - 0.05
    players[1, 1, MODEL_JOINT_IDS[5]] = 0.0  # not detected
    joints = model_joints(players)
    assert joints.shape == (2, 2, 8, 3)
    assert np.isnan(joints[0, 0, 2, :2]).all() and joints[0, 0, 2, 2] == pytest.approx(MIN_CONFIDENCE - 0.05)
    assert np.isnan(joints[1, 1, 5, :2]).all() and joints[1, 1, 5, 2] == 0
    assert np.isfinite(joints[..., :2]).sum() == 2 * (2 * 2 * 8 - 2)
    assert np.isnan(model_joints(players, min_confidence=0.95)[..., :2]).all()


def test_table_from_an_openpose_folder(twin, tmp_path):
    bodies, cameras, keypoints, _ = twin
    camera, people = cameras[0], keypoints[0][:60]
    for frame, frame_people in enumerate(people):
        detected = (frame_people[..., 2] > 0).any(axis=-1)
        write_keypoints_json(tmp_path, "s00_cam0", frame, frame_people[detected])
    time_ns = 1_767_225_600_000_000_000 + 10_000_000 * np.arange(len(people), dtype=np.int64)
    table = pose2d_table(tmp_path, camera, time_ns)
    assert list(table.columns) == list(POSE2D.columns) and len(table) == 2 * len(people)
    near = table[table.player == "near"]
    assert near.time_ns.tolist() == time_ns.tolist()
    expected = model_joints(fix_limb_swaps(assign_sides(people, camera)))[:, 0]
    np.testing.assert_allclose(near.filter(regex="_u$").to_numpy(), expected[..., 0], atol=1e-3)
    write_table(table, tmp_path / "cam0.parquet", POSE2D, Provenance.of("pose2d"))
    assert read_table(tmp_path / "cam0.parquet", POSE2D).equals(table)

    with pytest.raises(ValueError, match=f"{tmp_path}.*expected frames 0..60"):
        pose2d_table(tmp_path, camera, np.append(time_ns, time_ns[-1] + 10_000_000))
    bad = tmp_path / "s00_cam0_000000000007_keypoints.json"
    bad.write_text('{"version":1.3,"people":[{"pose_keypoints_2d":[1,2')
    with pytest.raises(ValueError, match="s00_cam0_000000000007_keypoints.json"):
        pose2d_table(tmp_path, camera, time_ns)


def _write_in_model_order(folder, people, model):
    """One {name}.{frame:05d}.json per frame of BODY_25 people (F, P, 25, 3), serialised in the model's
    keypoint order by joint name (joints BODY_25 lacks, such as BODY_25B's HeadTop, undetected)."""
    names = [BODY25_NAME.get(name, name) for name in KEYPOINT_MODELS[model]]
    order = [BODY25.index(name) if name in BODY25 else None for name in names]
    for frame, frame_people in enumerate(people):
        detected = frame_people[(frame_people[..., 2] > 0).any(axis=-1)]
        poses = [[v for j in order for v in (person[j] if j is not None else (0, 0, 0))]
                 for person in detected.tolist()]
        doc = {"version": 1.3, "people": [{"person_id": [-1], "pose_keypoints_2d": pose} for pose in poses]}
        (folder / f"s00_cam0.{frame:05d}.json").write_text(json.dumps(doc))


@pytest.mark.parametrize("model", ["BODY_25B", "COCO", "HALPE_26"])
def test_table_from_any_model_and_layout(twin, tmp_path, model):
    """The twin's people written in another model's order give the BODY_25 data's model joints: the
    8 joints map by name, the rest differs only where the model lacks a BODY_25 joint (a derived neck
    or mid-hip, no feet in COCO), which here moves no assignment."""
    _, cameras, keypoints, _ = twin
    camera, people = cameras[0], keypoints[0][:60]
    time_ns = 10_000_000 * np.arange(len(people), dtype=np.int64)
    tables = {}
    for name in ("BODY_25", model):
        (tmp_path / name).mkdir()
        _write_in_model_order(tmp_path / name, people, name)
        tables[name] = pose2d_table(tmp_path / name, camera, time_ns, model=name, pattern="dotted")
    table = tables[model]
    assert list(table.columns) == list(POSE2D.columns)
    assert np.isfinite(table.filter(regex="_u$").to_numpy()).mean() > 0.5
    np.testing.assert_array_equal(table.iloc[:, 2:].to_numpy(), tables["BODY_25"].iloc[:, 2:].to_numpy())
    count = 3 * len(KEYPOINT_MODELS[model])
    if count == 75:  # BODY_25B read as the default BODY_25: other joints, which no count can reveal
        wrong = pose2d_table(tmp_path / model, camera, time_ns)
        assert not np.allclose(wrong.iloc[:, 2:].to_numpy(), table.iloc[:, 2:].to_numpy(), equal_nan=True)
    else:
        with pytest.raises(ValueError, match=rf"s00_cam0.00000.json: person 0 has {count} "):
            pose2d_table(tmp_path / model, camera, time_ns)  # declared BODY_25 by default


@given(x=st.floats(-1.4, 1.4), depth=st.floats(0.1, 2.5), side=st.sampled_from([1, -1]),
       cam=st.integers(0, 3))
def test_floor_position_of_joints_at_their_typical_heights(x, depth, side, cam):
    """Joints on a vertical line at their typical heights give back exactly where the person stands."""
    camera = make_rig(np.random.default_rng(5), 4, 480, 360)[cam]
    where = np.array([x, side * (1.37 + depth)])
    person = np.zeros((25, 3))
    for joint, height in TYPICAL_HEIGHTS.items():
        person[joint] = [*camera.project(np.array([*where, height]))[0], 0.8]
    np.testing.assert_allclose(floor_positions(person[None, None], camera)[0, 0], where, atol=1e-5)


@given(st.lists(st.tuples(st.integers(0, 30), st.integers(0, 10), st.floats(0.0, 10.0)), max_size=7))
def test_best_tracklets_is_the_best_non_overlapping_set(intervals):
    """Weighted interval scheduling against brute force over all subsets."""
    first = np.array([a for a, _, _ in intervals], int)
    last = first + np.array([n for _, n, _ in intervals], int)
    weight = np.array([w for _, _, w in intervals], float)
    chosen = best_tracklets(first, last, weight)
    spans = sorted(zip(first[chosen], last[chosen], strict=True))
    assert all(b[0] > a[1] for a, b in itertools.pairwise(spans))
    best = 0.0
    for k in range(len(intervals) + 1):
        for subset in itertools.combinations(range(len(intervals)), k):
            s = sorted(subset, key=lambda i: first[i])
            if all(first[j] > last[i] for i, j in itertools.pairwise(s)):
                best = max(best, weight[list(subset)].sum())
    assert weight[chosen].sum() == pytest.approx(best)
