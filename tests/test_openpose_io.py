"""OpenPose JSON as OpenPose writes it, read back; the OpenPose simulator's behaviour."""

import json

import numpy as np
import pytest

from pingpong.io.openpose_json import (
    format_keypoints_json,
    keypoints_filename,
    read_keypoints_folder,
    read_keypoints_json,
    write_keypoints_json,
)
from pingpong.twin.openpose_sim import simulate_openpose
from pingpong.twin.rig import make_rig

OPENPOSE_KEYS = ["person_id", "pose_keypoints_2d", "face_keypoints_2d", "hand_left_keypoints_2d",
                 "hand_right_keypoints_2d", "pose_keypoints_3d", "face_keypoints_3d",
                 "hand_left_keypoints_3d", "hand_right_keypoints_3d"]


def test_json_has_openposes_fields_and_round_trips(tmp_path):
    rng = np.random.default_rng(0)
    people = np.column_stack([rng.uniform(0, 480, 50), rng.uniform(0, 360, 50), rng.uniform(0, 1, 50)])
    people = people.reshape(2, 25, 3)
    people[0, 7] = 0  # an undetected joint
    path = write_keypoints_json(tmp_path, "s01_cam3", 42, people)
    assert path.name == "s01_cam3_000000000042_keypoints.json" == keypoints_filename("s01_cam3", 42)
    text = path.read_text()
    assert text.startswith('{"version":1.3,"people":[{"person_id":[-1],"pose_keypoints_2d":[')
    doc = json.loads(text)
    assert doc["version"] == 1.3 and [list(p) for p in doc["people"]] == [OPENPOSE_KEYS] * 2
    assert all(p[k] == [] for p in doc["people"] for k in OPENPOSE_KEYS[2:])
    assert doc["people"][0]["pose_keypoints_2d"][21:24] == [0, 0, 0]
    np.testing.assert_allclose(read_keypoints_json(path), people, rtol=1e-5, atol=1e-3)


def test_folder_reader_sorts_frames_and_pads_people(tmp_path):
    write_keypoints_json(tmp_path, "s_cam0", 2, np.ones((1, 25, 3)))
    write_keypoints_json(tmp_path, "s_cam0", 0, np.full((3, 25, 3), 2.0))
    write_keypoints_json(tmp_path, "s_cam0", 1, np.zeros((0, 25, 3)))
    frames, keypoints = read_keypoints_folder(tmp_path)
    assert frames.tolist() == [0, 1, 2] and keypoints.shape == (3, 3, 25, 3)
    assert (keypoints[1] == 0).all() and (keypoints[2, 0] == 1).all() and (keypoints[2, 1:] == 0).all()


def test_bad_json_names_the_file(tmp_path):
    bad = tmp_path / "x_000000000001_keypoints.json"
    bad.write_text('{"version":1.3,"people":[{"pose_keypoints_2d":[1,2]}]}')
    with pytest.raises(ValueError, match="x_000000000001_keypoints.json.*BODY_25"):
        read_keypoints_json(bad)


def test_empty_frame_format():
    assert format_keypoints_json(np.zeros((0, 25, 3))) == '{"version":1.3,"people":[]}'


STANDING = np.array([
    (0, -0.08, 1.62), (0, 0, 1.45), (-0.19, 0, 1.43), (-0.24, -0.15, 1.20), (-0.20, -0.35, 1.05),
    (0.19, 0, 1.43), (0.26, -0.05, 1.15), (0.28, -0.08, 0.90), (0, 0, 0.95), (-0.1, 0, 0.95),
    (-0.12, -0.05, 0.52), (-0.13, 0, 0.08), (0.1, 0, 0.95), (0.12, -0.05, 0.52), (0.13, 0, 0.08),
    (-0.035, -0.07, 1.66), (0.035, -0.07, 1.66), (-0.08, 0, 1.64), (0.08, 0, 1.64), (0.14, -0.18, 0.02),
    (0.18, -0.16, 0.02), (0.13, 0.04, 0.03), (-0.14, -0.18, 0.02), (-0.18, -0.16, 0.02),
    (-0.13, 0.04, 0.03)]) + [0, 0, -0.76]


def test_simulated_keypoints_are_noisy_projections_in_shuffled_order():
    rng = np.random.default_rng(1)
    camera = make_rig(rng)[2]  # at the -y end, looking at the far (+y) player
    far_player = STANDING + [0.0, 2.4, 0.0]
    bystander = STANDING + [2.5, 1.0, 0.0]
    truths = [camera.project(far_player), camera.project(bystander)]
    errors, first_is_player = [], []
    for _ in range(200):
        people = simulate_openpose(camera, [far_player, bystander], rng, swap_rate=0.0)
        assert people.shape[1:] == (25, 3)
        which = []
        for person in people:
            detected = person[:, 2] > 0
            k = int(np.argmin([np.median(np.linalg.norm(person[detected, :2] - t[detected], axis=1))
                               for t in truths]))
            errors.append(person[detected, :2] - truths[k][detected])
            assert (person[~detected] == 0).all()
            which.append(k)
        first_is_player.append(which[0] == 0)
    sigma = np.concatenate(errors).std()
    assert 0.8 < sigma < 2.5  # 3 px at 1440 px width -> 1 px at 480, 1.5x on wrists and ankles
    assert 0.3 < np.mean(first_is_player) < 0.7  # random order


def test_out_of_image_joints_are_zero_and_swaps_happen():
    rng = np.random.default_rng(2)
    camera = make_rig(rng)[2]
    player = STANDING + [0.0, 2.4, 0.0]
    px = camera.project(player)
    people = simulate_openpose(camera, [player], rng, swap_rate=1.0)
    assert len(people) == 1
    # with swap_rate 1 one limb's right and left joints trade places
    right_wrist_near_left = np.linalg.norm(people[0, 4, :2] - px[7]) < 8 or \
        np.linalg.norm(people[0, 11, :2] - px[14]) < 8 or np.linalg.norm(people[0, 24, :2] - px[21]) < 8
    assert right_wrist_near_left
    behind = simulate_openpose(camera, [player - [0.0, 10.0, 0.0]], rng)  # behind the camera
    assert behind.shape == (0, 25, 3)
