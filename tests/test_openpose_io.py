"""OpenPose JSON as OpenPose writes it, read back; the OpenPose simulator's behaviour."""

import json

import numpy as np
import pytest

from pingpong.frames import BODY25, MODEL_JOINT_IDS
from pingpong.io.openpose_json import (
    BODY25_NAME,
    KEYPOINT_MODELS,
    format_keypoints_json,
    keypoints_filename,
    list_frame_files,
    read_keypoints_folder,
    read_keypoints_json,
    to_body25,
    write_keypoints_json,
)
from pingpong.twin.openpose_sim import simulate_openpose, simulate_openpose_frames
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


# A person whose BODY_25 joint j is at pixel (10 + 7j, 300 - 5j) with confidence 0.5 + 0.02j; a model's
# own joints that BODY_25 lacks (UpperNeck, HeadTop, Head) sit at (1, 2) with confidence 0.9.
KNOWN = np.array([(10 + 7 * j, 300 - 5 * j, 0.5 + 0.02 * j) for j in range(25)])


def in_model_order(person: np.ndarray, model: str) -> np.ndarray:
    """(K, 3) a BODY_25 person (25, 3) serialised in the model's keypoint order, by joint name."""
    names = [BODY25_NAME.get(name, name) for name in KEYPOINT_MODELS[model]]
    return np.array([person[BODY25.index(n)] if n in BODY25 else (1.0, 2.0, 0.9) for n in names])


def write_model_json(path, people) -> None:
    path.write_text(json.dumps({"version": 1.3, "people": [
        {"person_id": [-1], "pose_keypoints_2d": np.ravel(p).tolist()} for p in people]}))


def midpoint(a: str, b: str) -> np.ndarray:
    ends = KNOWN[[BODY25.index(a), BODY25.index(b)]]
    return np.array([*ends[:, :2].mean(axis=0), ends[:, 2].min()])


@pytest.mark.parametrize("model", list(KEYPOINT_MODELS))
def test_every_model_maps_by_name_to_body25(tmp_path, model):
    path = tmp_path / f"cam.{7:05d}.json"
    write_model_json(path, [in_model_order(KNOWN, model), np.zeros((len(KEYPOINT_MODELS[model]), 3))])
    people = read_keypoints_json(path, model)
    assert people.shape == (2, 25, 3) and (people[1] == 0).all()
    np.testing.assert_allclose(people[0, list(MODEL_JOINT_IDS)], KNOWN[list(MODEL_JOINT_IDS)])
    names = {BODY25_NAME.get(n, n) for n in KEYPOINT_MODELS[model]}
    for joint, (a, b) in {"Neck": ("RShoulder", "LShoulder"), "MidHip": ("RHip", "LHip")}.items():
        expected = KNOWN[BODY25.index(joint)] if joint in names else midpoint(a, b)  # derived if lacking
        np.testing.assert_allclose(people[0, BODY25.index(joint)], expected)
    lacking = [j for j, n in enumerate(BODY25) if n not in names | {"Neck", "MidHip"}]
    assert (people[0, lacking] == 0).all()  # absent: the feet in COCO, nothing elsewhere
    assert len(lacking) == {"COCO": 6}.get(model, 0)


def test_a_derived_joint_needs_both_ends():
    person = in_model_order(KNOWN, "BODY_25B")
    person[KEYPOINT_MODELS["BODY_25B"].index("LHip")] = 0  # not detected
    body = to_body25(person[None], "BODY_25B")[0]
    assert (body[BODY25.index("MidHip")] == 0).all()
    np.testing.assert_allclose(body[BODY25.index("Neck")], midpoint("RShoulder", "LShoulder"))


def test_body25b_declared_as_such_equals_body25(tmp_path):
    rng = np.random.default_rng(4)
    people = np.column_stack([rng.uniform(0, 480, 75), rng.uniform(0, 360, 75), rng.uniform(0.1, 1, 75)])
    people = people.reshape(3, 25, 3)
    write_keypoints_json(tmp_path, "b25", 0, people)
    write_model_json(tmp_path / "b25b.json", [in_model_order(p, "BODY_25B") for p in people])
    as_body25 = read_keypoints_json(tmp_path / keypoints_filename("b25", 0))
    as_body25b = read_keypoints_json(tmp_path / "b25b.json", "BODY_25B")
    np.testing.assert_allclose(as_body25b[:, list(MODEL_JOINT_IDS)], as_body25[:, list(MODEL_JOINT_IDS)],
                               rtol=1e-5, atol=1e-3)
    # the count cannot tell them apart: BODY_25B read as BODY_25 gives other joints without a word
    wrong = read_keypoints_json(tmp_path / "b25b.json")
    assert not np.allclose(wrong[:, list(MODEL_JOINT_IDS)], as_body25[:, list(MODEL_JOINT_IDS)], atol=1)


def test_count_mismatch_names_file_person_and_counts(tmp_path):
    path = tmp_path / "cam_000000000003_keypoints.json"
    write_model_json(path, [in_model_order(KNOWN, "BODY_25"), in_model_order(KNOWN, "COCO")])
    with pytest.raises(ValueError, match=r"cam_000000000003_keypoints.json: person 1 has 54 .*expected 75 .*"
                                         r"BODY_25; 54 values fit COCO"):
        read_keypoints_json(path)
    with pytest.raises(ValueError, match=r"person 0 has 75 .*expected 78 .*HALPE_26; 75 values fit "
                                         r"BODY_25 or BODY_25B .*cannot be told apart.*declare"):
        read_keypoints_json(path, "HALPE_26")
    with pytest.raises(ValueError, match="unknown keypoint model 'BODY25'.*BODY_25, BODY_25B, COCO, HALPE_"):
        read_keypoints_json(path, "BODY25")


def _touch_frames(folder, names):
    for name in names:
        write_model_json(folder / name, [])


@pytest.mark.parametrize("name", ["cam2.{:05d}.json", "cam2.{}.json", "cam2_{:012d}_keypoints.json"])
def test_both_layouts_found_in_numeric_order(tmp_path, name):
    _touch_frames(tmp_path, [name.format(frame) for frame in (11, 9, 8, 10)])
    (tmp_path / "notes.txt").write_text("ignored")
    frames = [frame for frame, _ in list_frame_files(tmp_path)]
    assert frames == [8, 9, 10, 11]  # "cam2.10.json" sorts before "cam2.9.json" as text
    assert [p.name for _, p in list_frame_files(tmp_path)][2] == name.format(10)


def test_declared_pattern(tmp_path):
    _touch_frames(tmp_path, ["cam2.00001.json", "cam2.00000.json", "take3-frame0.json", "take3-frame1.json",
                             keypoints_filename("cam2", 0), keypoints_filename("cam2", 1)])
    with pytest.raises(ValueError, match=r"2 layouts mixed \(openpose: e.g. 'cam2_0+_keypoints.json', "
                                         r"dotted: e.g. 'cam2.00000.json'\)"):
        list_frame_files(tmp_path)
    assert [p.name for _, p in list_frame_files(tmp_path, "dotted")] == ["cam2.00000.json", "cam2.00001.json"]
    assert [p.name for _, p in list_frame_files(tmp_path, r"take3-frame(\d+)\.json")] == [
        "take3-frame0.json", "take3-frame1.json"]
    with pytest.raises(ValueError, match="has 0 groups; expected one, the frame number"):
        list_frame_files(tmp_path, r"take3-frame\d+\.json")
    with pytest.raises(ValueError, match=r"take3-frame0.json: the group .* holds 'take3'"):
        list_frame_files(tmp_path, r"(take3)-frame0\.json")


def test_empty_or_unmatched_folder_names_the_expected_patterns(tmp_path):
    expected = r"expected names \{name\}_\{frame:012d\}_keypoints.json .* or \{name\}.\{frame\}.json"
    with pytest.raises(ValueError, match=f"{tmp_path}: no per-frame keypoints files; {expected}.*is empty"):
        read_keypoints_folder(tmp_path)
    _touch_frames(tmp_path, ["cam2_keypoints_000001.json", "cam2_keypoints_000002.json"])
    found = r"found e.g. 'cam2_keypoints_000001.json' \(2 files in all\)"
    with pytest.raises(ValueError, match=f"{tmp_path}: .*{expected}.*; {found}"):
        read_keypoints_folder(tmp_path)
    with pytest.raises(ValueError, match="not a folder"):
        read_keypoints_folder(tmp_path / "missing")


def test_gaps_and_duplicate_frames_are_named(tmp_path):
    _touch_frames(tmp_path, ["cam2.0.json", "cam2.1.json", "cam2.3.json"])
    with pytest.raises(ValueError, match=r"frame 2 missing \(files of frames 1 then 3\)"):
        read_keypoints_folder(tmp_path)
    _touch_frames(tmp_path, ["cam2.2.json", "cam2.0003.json"])
    with pytest.raises(ValueError, match=r"frame 3 has more than one file \(cam2.0003.json, cam2.3.json\)"):
        read_keypoints_folder(tmp_path)


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


def test_frames_at_once_drop_absent_people_and_hide_the_occluded():
    rng = np.random.default_rng(3)
    camera = make_rig(rng)[2]  # at the -y end, looking along +y
    far_player = STANDING + [0.0, 2.4, 0.0]
    in_front = far_player + 0.2 * (camera.center - far_player.mean(axis=0))  # on the line of sight: covers it
    beside = far_player + [1.5, 0.0, 0.0]
    bodies = np.stack([np.stack([far_player] * 4), np.stack([in_front, beside, beside, beside])])
    bodies[1, 3] = np.nan  # the second person leaves in the last frame
    frames = simulate_openpose_frames(camera, bodies, rng, swap_rate=0.0)
    assert [len(f) for f in frames] == [2, 2, 2, 1]
    truths = camera.project(far_player), camera.project(in_front)

    def player_confidence(people):
        def off(p, t):  # median pixel distance of a person's detected joints to a projection
            return np.median(np.linalg.norm(p[p[:, 2] > 0, :2] - t[p[:, 2] > 0], axis=1))
        k = int(np.argmin([off(p, truths[0]) - off(p, truths[1]) for p in people]))
        return people[k][:, 2][people[k][:, 2] > 0]

    assert np.median(player_confidence(frames[0])) < 0.45  # behind the nearer person: low confidences
    assert np.median(player_confidence(frames[1])) > 0.5  # in the clear
