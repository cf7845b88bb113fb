"""2D poses: OpenPose people tracked per camera and matched to the near/far players across cameras,
checked against the twin's truth.

The data are simulated here (a short session, a 2-camera rig at 480x360, OpenPose's errors per
frame), so CI needs no recordings. A detection's identity is the truth person whose projected
joints are nearest (median over its detected joints).
"""

import json
import warnings

import numpy as np
import pytest

from pingpong.common.artifacts import Provenance, read_table, write_table
from pingpong.curation.tracks import JOINT_VIEWS
from pingpong.frames import BODY25, MODEL_JOINT_IDS, MODEL_JOINTS
from pingpong.io.openpose_json import KEYPOINT_MODELS, pose_keypoints, write_keypoints_json
from pingpong.perception.association import associate
from pingpong.perception.pose2d import (
    MIN_CONFIDENCE,
    model_joints,
    pose2d_table,
    tracked_people,
)
from pingpong.perception.pose3d import PoseSceneError, pose3d_table
from pingpong.perception.scene import default_players_scene
from pingpong.perception.schemas import POSE2D, POSE2D_VALUES, joint_columns
from pingpong.perception.triangulation import reprojection_gate_px
from pingpong.twin.openpose_sim import LIMB_SWAPS, default_keypoint_errors, simulate_openpose
from pingpong.twin.players import bystander_joints
from pingpong.twin.rig import make_rig
from pingpong.twin.session import FaultRates, simulate_session
from pingpong.twin.truth import JOINT_COLUMNS

PEOPLE = ("near", "far", "bystander")
ASSOCIATION_SHARE = 0.02  # config perception.association_share's default


def _openpose(camera, bodies, rng, swap_rate=0.01):
    """(F, P, 25, 3) simulated OpenPose people of every frame of bodies (F, 3, 25, 3), zero-padded."""
    frames = [simulate_openpose(camera, [b for b in bodies[f] if not np.isnan(b).all()], rng,
                                 default_keypoint_errors(swap_rate=swap_rate))
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
    people = keypoints[0][:60]
    for frame, frame_people in enumerate(people):
        detected = (frame_people[..., 2] > 0).any(axis=-1)
        write_keypoints_json(tmp_path, "s00_cam0", frame, frame_people[detected])
    time_ns = 1_767_225_600_000_000_000 + 10_000_000 * np.arange(len(people), dtype=np.int64)
    table = pose2d_table(tmp_path, time_ns)
    assert list(table.columns) == ["time_ns", "person", *joint_columns(BODY25, POSE2D_VALUES)]
    assert set(POSE2D.columns) <= set(table.columns)
    assert table.time_ns.unique().tolist() == time_ns.tolist()
    tracked, track = tracked_people(people)
    expected = model_joints(tracked, joints=BODY25)[track >= 0]
    assert len(table) == len(expected) + ((track < 0).all(axis=1)).sum()
    rows = table[table.person >= 0].sort_values(["time_ns", "person"])
    f, lane = np.nonzero(track >= 0)
    order = np.lexsort((track[f, lane], f))
    np.testing.assert_allclose(rows.filter(regex="_u$").to_numpy(), expected[order][..., 0], atol=1e-3)
    write_table(table, tmp_path / "cam0.parquet", POSE2D, Provenance.of("pose2d"))
    assert read_table(tmp_path / "cam0.parquet", POSE2D).equals(table)

    with pytest.raises(ValueError, match=f"{tmp_path}.*expected frames 0..60"):
        pose2d_table(tmp_path, np.append(time_ns, time_ns[-1] + 10_000_000))
    bad = tmp_path / "s00_cam0_000000000007_keypoints.json"
    bad.write_text('{"version":1.3,"people":[{"pose_keypoints_2d":[1,2')
    with pytest.raises(ValueError, match="s00_cam0_000000000007_keypoints.json"):
        pose2d_table(tmp_path, time_ns)


OWN_ABOVE_NOSE_PX = 10.0  # _write_in_model_order's k-th keypoint BODY_25 lacks: (k + 1) x this above the nose


def _own_keypoint(person: list, k: int) -> list:
    """A model's k-th keypoint that BODY_25 lacks (BODY_25B's UpperNeck, HeadTop; Halpe's Head) of a BODY_25
    person: above its nose, with the nose's confidence."""
    u, v, confidence = person[BODY25.index("Nose")]
    return [u, v - (k + 1) * OWN_ABOVE_NOSE_PX, confidence]


def _write_in_model_order(folder, people, model):
    """One {name}.{frame:05d}.json per frame of BODY_25 people (F, P, 25, 3), serialised in the model's
    keypoint order by joint name (the keypoints BODY_25 lacks as _own_keypoint places them)."""
    names = pose_keypoints(model)
    own = [name for name in names if name not in BODY25]
    for frame, frame_people in enumerate(people):
        detected = frame_people[(frame_people[..., 2] > 0).any(axis=-1)]
        poses = [[v for name in names for v in (person[BODY25.index(name)] if name in BODY25
                                                else _own_keypoint(person, own.index(name)))]
                 for person in detected.tolist()]
        doc = {"version": 1.3, "people": [{"person_id": [-1], "pose_keypoints_2d": pose} for pose in poses]}
        (folder / f"s00_cam0.{frame:05d}.json").write_text(json.dumps(doc))


@pytest.mark.parametrize("model", list(KEYPOINT_MODELS))
def test_table_from_any_model_and_layout(twin, tmp_path, model):
    """The twin's people written in a model's order give every keypoint of the model, in its order: those
    BODY_25 names as the BODY_25 data give them, by BODY_25's name (the 8 model joints among them), and the
    others (BODY_25B's UpperNeck and HeadTop, Halpe's Head) by the model's own name, as written. The
    tracking follows BODY_25's joints and differs only where the model lacks one (a derived neck or
    mid-hip, no feet in COCO), which here moves no assignment."""
    _, cameras, keypoints, _ = twin
    people = keypoints[0][:60]
    time_ns = 10_000_000 * np.arange(len(people), dtype=np.int64)
    tables = {}
    for name in {"BODY_25", model}:
        (tmp_path / name).mkdir()
        _write_in_model_order(tmp_path / name, people, name)
        tables[name] = pose2d_table(tmp_path / name, time_ns, model=name, pattern="dotted")
    table = tables[model]
    names = pose_keypoints(model)  # no derived neck or mid-hip
    assert list(table.columns) == ["time_ns", "person", *joint_columns(names, POSE2D_VALUES)]
    assert set(POSE2D.columns) <= set(table.columns) and set(MODEL_JOINTS) <= set(names)
    assert len(names) == len(KEYPOINT_MODELS[model])
    assert np.isfinite(table.filter(regex="_u$").to_numpy()).mean() > 0.5
    body25 = tables["BODY_25"]
    shared = list(joint_columns([name for name in names if name in BODY25], POSE2D_VALUES))
    np.testing.assert_array_equal(table[shared].to_numpy(), body25[shared].to_numpy())
    own = [name for name in names if name not in BODY25]
    assert own == {"BODY_25B": ["UpperNeck", "HeadTop"], "HALPE_26": ["Head"]}.get(model, [])
    for k, name in enumerate(own):
        assert table[f"{name}_u"].notna().mean() > 0.5
        np.testing.assert_array_equal(table[[f"{name}_u", f"{name}_conf"]], body25[["Nose_u", "Nose_conf"]])
        np.testing.assert_allclose(table[f"{name}_v"], body25["Nose_v"] - (k + 1) * OWN_ABOVE_NOSE_PX)
    if model == "BODY_25":
        return
    count = 3 * len(KEYPOINT_MODELS[model])
    if count == 75:  # BODY_25B read as the default BODY_25: no count can tell, the skeletons' lengths do
        with pytest.raises(ValueError, match=r"s00_cam0.\d{5}.json: keypoints declared BODY_25 look like "
                                             r"BODY_25B: .*\(BODY_25B likely\)"):
            pose2d_table(tmp_path / model, time_ns)
    else:
        with pytest.raises(ValueError, match=rf"s00_cam0.00000.json: person 0 has {count} "):
            pose2d_table(tmp_path / model, time_ns)  # declared BODY_25 by default




def test_tracklets_follow_one_person(twin):
    """Every tracklet of each camera holds one truth person (bystanders too) in >= 99 % of its frames, and
    the model joints lie as near that person's projected joints as the detections do (median; limb swaps
    undone, no error added)."""
    bodies, cameras, keypoints, _ = twin
    for camera, people in zip(cameras, keypoints, strict=True):
        truth_px = _projected(camera, bodies)
        tracked, track = tracked_people(people)
        who = _identity(tracked, truth_px)
        for k in np.unique(track[track >= 0]):
            ids = who[track == k]
            assert np.mean(ids == np.bincount(ids[ids >= 0]).argmax()) >= 0.99, k
        joints = model_joints(tracked)
        f, lane = np.nonzero(track >= 0)
        mine = truth_px[f, who[f, lane]][:, list(MODEL_JOINT_IDS)]
        errors = np.linalg.norm(joints[f, lane, :, :2] - mine, axis=-1)
        raw_who = _identity(people, truth_px)
        g, k = np.nonzero(raw_who >= 0)
        raw = people[g, k][:, list(MODEL_JOINT_IDS)]
        raw_truth = truth_px[g, raw_who[g, k]][:, list(MODEL_JOINT_IDS)]
        raw_errors = np.linalg.norm(raw[..., :2] - raw_truth, axis=-1)
        assert np.nanmedian(errors) <= 1.02 * np.median(raw_errors[raw[..., 2] > 0])


def _associated(cameras, keypoints):
    """Each camera's OpenPose people (F, P, 25, 3) tracked as pose2d does, then matched across cameras:
    the tracked people per camera ((F, L, 25, 3), tracklet ids (F, L)) and the choice (F, 2, C) of a lane
    per camera for near and far (-1: none)."""
    tracked = [tracked_people(k) for k in keypoints]
    arrays = []
    for people, track in tracked:
        joints = model_joints(people)
        arrays.append((joints[..., :2], joints[..., 2], track))
    gate = reprojection_gate_px(cameras, ASSOCIATION_SHARE)
    return tracked, associate(cameras, arrays, default_players_scene(), gate)


def _chosen(tracked, choice):
    """(F, 2, C, 25, 3) the keypoints each camera gives near and far, zeros where none."""
    frames = np.arange(len(choice))[:, None]
    return np.stack([np.where((choice[..., c] >= 0)[..., None, None],
                              people[frames, np.maximum(choice[..., c], 0)], 0.0)
                     for c, (people, _) in enumerate(tracked)], axis=2)


def _check_choice(cameras, bodies, tracked, choice, min_accuracy=0.99):
    """Per camera and player, over the frames where the camera detects the player and at least one other
    camera does too (the association needs two views): the camera gives the player's slot the player's
    own detection in >= min_accuracy of them, else none (a view whose joints disagree, a limb swapped or
    joints hidden, is left out). No camera ever gives a slot the other player or a bystander."""
    frames = np.arange(len(choice))[:, None]
    who = [_identity(people, _projected(cam, bodies)) for cam, (people, _) in zip(cameras, tracked,
                                                                                  strict=True)]
    detected = np.stack([(w[..., None] == np.arange(len(PEOPLE))).any(axis=1) for w in who], axis=-1)
    for c, w in enumerate(who):
        chosen_as = np.where(choice[..., c] >= 0, w[frames, np.maximum(choice[..., c], 0)], -1)  # (F, 2)
        assert not (chosen_as == 2).any(), f"cam {c}: a bystander was chosen for a player"
        for side in range(2):
            assert not (chosen_as[:, side] == 1 - side).any(), f"cam {c}: the players mixed up"
            mask = detected[:, side, c] & (detected[:, side].sum(axis=-1) >= 2)
            accuracy = np.mean(chosen_as[mask, side] == side)
            assert accuracy >= min_accuracy, f"cam {c} {PEOPLE[side]}: {accuracy:.4f} of frames chosen right"
    return who, detected


def test_sides_match_the_truth(twin):
    """On the twin's 2-camera rig, a bystander in half the frames: each camera gives each player's slot
    the player's detection in >= 99 % of the frames where both cameras detect him, a bystander never
    (the tiny run's 3 cameras: test_association)."""
    bodies, cameras, keypoints, _ = twin
    who, detected = _check_choice(cameras, bodies, *_associated(cameras, keypoints))
    assert (detected[:, 0] & detected[:, 1]).all(axis=-1).mean() > 0.9
    assert detected[:, 2].any(axis=-1).sum() > 100  # the test saw a bystander


def test_bystander_at_the_table_corner_while_the_player_is_unseen(twin):
    """A bystander just beside the near end (0.12 m from the near area, inside its margin) is never taken
    for the near player, even in the 0.3 s stretches in which no camera sees the near player: the
    bystander's tracklets were seen beside the player's before."""
    bodies, cameras, _, rng = twin
    bodies = bodies[:450].copy()
    bystander = bystander_joints(np.arange(len(bodies)) / 100, rng)  # in the room all the time
    bodies[:, 2] = bystander + np.array([1.6, 1.3, 0.0]) - bystander[:, 8].mean(axis=0) * [1, 1, 0]
    for start in range(100, len(bodies), 200):
        bodies[start:start + 30, 0] = np.nan
    keypoints = [_openpose(camera, bodies, rng) for camera in cameras]
    who, detected = _check_choice(cameras, bodies, *_associated(cameras, keypoints))
    assert detected[:, 2].all(axis=-1).mean() > 0.9  # both cameras saw the bystander


def test_person_order_and_padding_do_not_matter(twin):
    """Each frame's people shuffled and padded with undetected people: the same keypoints for each slot."""
    _, cameras, keypoints, _ = twin
    people = [k[:300] for k in keypoints]
    rng = np.random.default_rng(3)
    shuffled = []
    for k in people:
        padded = np.concatenate([k, np.zeros((len(k), 2, 25, 3))], axis=1)
        shuffled.append(np.stack([frame[rng.permutation(len(frame))] for frame in padded]))
    before, after = _chosen(*_associated(cameras, people)), _chosen(*_associated(cameras, shuffled))
    assert (before[..., 2] > 0).any(axis=(-1, -2)).mean() > 0.9
    np.testing.assert_array_equal(after, before)


def _write_folder(folder, people):
    folder.mkdir()
    for frame, frame_people in enumerate(people):
        write_keypoints_json(folder, "s00_cam", frame, frame_people[(frame_people[..., 2] > 0).any(axis=-1)])


def test_missing_people_and_empty_frames(twin, tmp_path):
    """A camera that sees nobody for 50 frames and misses the far player for 60 more: pose2d keeps one row
    of gaps (person -1) for each empty frame, the association leaves the slots it cannot match in two
    views empty and errs nowhere else, and pose3d has NaN joints seen by no camera (`_n` 0) there. A camera
    that never sees anyone, or only undetected people, matches nobody; all cameras empty is an error."""
    bodies, cameras, keypoints, _ = twin
    bodies, people = bodies[:300], [k[:300].copy() for k in keypoints]
    ids = _identity(people[1], _projected(cameras[1], bodies))
    people[1][100:150] = 0  # nobody detected
    people[1][200:260][ids[200:260] == 1] = 0  # the far player missed
    tracked, choice = _associated(cameras, people)
    assert (choice[100:150] == -1).all() and (choice[200:260, 1] == -1).all()
    _check_choice(cameras, bodies, tracked, choice)

    time_ns = 10_000_000 * np.arange(len(bodies), dtype=np.int64)
    tables = []
    for c, k in enumerate(people):
        _write_folder(tmp_path / f"cam{c}", k)
        tables.append(pose2d_table(tmp_path / f"cam{c}", time_ns))
    empty = tables[1][tables[1].time_ns.isin(time_ns[100:150])]
    assert len(empty) == 50 and (empty.person == -1).all()
    assert empty.filter(regex="_[uv]$").isna().all(axis=None)
    assert (empty.filter(regex="_conf$") == 0).all(axis=None)
    pose, _ = pose3d_table(cameras, tables, default_players_scene(), ASSOCIATION_SHARE, 0.005, 4.0, False)
    assert len(pose) == 2 * len(time_ns)
    near, far = (pose[pose.player == p].set_index("time_ns") for p in ("near", "far"))
    for rows in (near.iloc[100:150], far.iloc[100:150], far.iloc[200:260]):
        assert rows.filter(regex="_[xyz]$").isna().all(axis=None)
        assert (rows.filter(regex="_views$") == 0).all(axis=None)
    # the near player still found (the two views' joints may disagree in a frame: the twin's detector errs
    # as COCO's sigmas say, swaps limbs and hides joints behind the trunk; 1 of these 60 frames)
    assert (near.iloc[200:260][list(JOINT_VIEWS)] >= 2).any(axis=1).mean() >= 0.95

    for n_people in (0, 3):  # nobody, or only undetected people, in every frame of one camera
        _, choice = _associated(cameras, [people[0], np.zeros((len(bodies), n_people, 25, 3))])
        assert (choice == -1).all()
    for c in range(2):
        _write_folder(tmp_path / f"nobody{c}", np.zeros((5, 0, 25, 3)))
    nobody = [pose2d_table(tmp_path / f"nobody{c}", time_ns[:5]) for c in range(2)]
    assert all(len(t) == 5 and (t.person == -1).all() for t in nobody)
    with pytest.raises(PoseSceneError, match="no joint of anyone in 3D in 5 frames"):
        pose3d_table(cameras, nobody, default_players_scene(), ASSOCIATION_SHARE, 0.005, 4.0, False)


def test_limb_swaps_are_undone(twin):
    """Single-frame swaps of an arm, leg or foot (here in 5 % of frames) are undone from 2D continuity
    along each tracklet: at least 90 % of the swapped limbs of every person (all joints seen and nearer
    the other side's truth)."""
    bodies, cameras, _, rng = twin
    camera, bodies = cameras[1], bodies[:400]
    people = _openpose(camera, bodies, rng, swap_rate=0.05)
    truth_px = _projected(camera, bodies)

    def swapped(people):
        who = _identity(people, truth_px)
        truth = truth_px[np.arange(len(people))[:, None], np.maximum(who, 0)]  # (F, P, 25, 2)
        count = 0
        for right, left in LIMB_SWAPS:
            both, mirrored = list(right + left), list(left + right)
            seen = (people[:, :, both, 2] > 0).all(axis=-1) & (who >= 0)
            straight = np.linalg.norm(people[:, :, both, :2] - truth[:, :, both], axis=-1).sum(axis=-1)
            crossed = np.linalg.norm(people[:, :, both, :2] - truth[:, :, mirrored], axis=-1).sum(axis=-1)
            count += np.sum(seen & (crossed < straight))
        return count

    before, after = swapped(people), swapped(tracked_people(people)[0])
    assert before >= 10 and after <= 0.1 * before, (before, after)
