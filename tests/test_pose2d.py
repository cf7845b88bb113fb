"""2D poses: OpenPose people assigned to the near/far players, checked against the twin's truth.

The data are simulated here (a short session, a 2-camera rig at 480x360, OpenPose's errors per
frame), so CI needs no recordings. A detection's identity is the truth person whose projected
joints are nearest (median over its detected joints).
"""

import json
import warnings

import numpy as np
import pytest

from pingpong.common.artifacts import Provenance, read_table, write_table
from pingpong.frames import BODY25, MODEL_JOINT_IDS
from pingpong.io.openpose_json import BODY25_NAME, KEYPOINT_MODELS, write_keypoints_json
from pingpong.perception.pose2d import MIN_CONFIDENCE, model_joints, pose2d_table, tracked_people
from pingpong.perception.schemas import POSE2D
from pingpong.twin.openpose_sim import simulate_openpose
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
    assert list(table.columns) == list(POSE2D.columns)
    assert table.time_ns.unique().tolist() == time_ns.tolist()
    tracked, track = tracked_people(people)
    expected = model_joints(tracked)[track >= 0]
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
    people = keypoints[0][:60]
    time_ns = 10_000_000 * np.arange(len(people), dtype=np.int64)
    tables = {}
    for name in ("BODY_25", model):
        (tmp_path / name).mkdir()
        _write_in_model_order(tmp_path / name, people, name)
        tables[name] = pose2d_table(tmp_path / name, time_ns, model=name, pattern="dotted")
    table = tables[model]
    assert list(table.columns) == list(POSE2D.columns)
    assert np.isfinite(table.filter(regex="_u$").to_numpy()).mean() > 0.5
    np.testing.assert_array_equal(table.iloc[:, 2:].to_numpy(), tables["BODY_25"].iloc[:, 2:].to_numpy())
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
    the model joints lie within 3 px (median) of that person's projected joints."""
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
        assert np.nanmedian(errors) < 3.0
