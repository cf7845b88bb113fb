"""OpenPose JSON as OpenPose writes it, read back; the OpenPose simulator's behaviour."""

import json
import logging
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pingpong.frames import BODY25, MODEL_JOINT_IDS, MODEL_JOINTS
from pingpong.io.openpose_json import (
    KEYPOINT_MODELS,
    MIN_PEOPLE,
    KeypointsFileError,
    check_declared_model,
    format_keypoints_json,
    keypoints_filename,
    list_frame_files,
    model_comparison,
    pose_keypoints,
    read_keypoints_folder,
    read_keypoints_json,
    reader_layout,
    to_reader_layout,
    write_keypoints_json,
)
from pingpong.twin.openpose_sim import (
    COCO_SIGMAS,
    default_keypoint_errors,
    object_scale,
    projected_people,
    self_hidden,
    simulate_openpose,
    simulate_openpose_frames,
)
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
    write_keypoints_json(tmp_path, "s_cam0", 0, np.full((3, 25, 3), 0.5))
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
OWN = (1.0, 2.0, 0.9)
# each model's keypoints that BODY_25 has no name for, in the model's order
OWN_KEYPOINTS = {"BODY_25": (), "BODY_25B": ("UpperNeck", "HeadTop"), "COCO": (), "HALPE_26": ("Head",)}


def in_model_order(person: np.ndarray, model: str) -> np.ndarray:
    """(K, 3) a BODY_25 person (25, 3) serialised in the model's keypoint order, by joint name."""
    return np.array([person[BODY25.index(n)] if n in BODY25 else OWN for n in pose_keypoints(model)])


def write_model_json(path, people) -> None:
    path.write_text(json.dumps({"version": 1.3, "people": [
        {"person_id": [-1], "pose_keypoints_2d": np.ravel(p).tolist()} for p in people]}))


def midpoint(a: str, b: str) -> np.ndarray:
    ends = KNOWN[[BODY25.index(a), BODY25.index(b)]]
    return np.array([*ends[:, :2].mean(axis=0), ends[:, 2].min()])


@pytest.mark.parametrize("model", list(KEYPOINT_MODELS))
def test_every_model_keeps_body25s_names_and_its_own(model):
    """Each keypoint named once, as BODY_25 names the joint (Halpe's Hip is MidHip) or by the model's own
    name, in the model's order; the 8 model joints in every model."""
    names = pose_keypoints(model)
    assert len(names) == len(set(names)) == len(KEYPOINT_MODELS[model])
    assert set(MODEL_JOINTS) <= set(names)
    assert tuple(n for n in names if n not in BODY25) == OWN_KEYPOINTS[model]
    renamed = {own: n for n, own in zip(names, KEYPOINT_MODELS[model], strict=True) if n != own}
    assert renamed == ({"Hip": "MidHip"} if model == "HALPE_26" else {})


@pytest.mark.parametrize("model", list(KEYPOINT_MODELS))
def test_every_model_reads_by_name(tmp_path, model):
    """BODY_25's 25 joints by name (Neck and MidHip derived where the model lacks them), then the model's
    keypoints BODY_25 lacks (BODY_25B's UpperNeck and HeadTop, Halpe's Head) in its order."""
    path = tmp_path / f"cam.{7:05d}.json"
    write_model_json(path, [in_model_order(KNOWN, model), np.zeros((len(KEYPOINT_MODELS[model]), 3))])
    people = read_keypoints_json(path, model)
    assert reader_layout(model) == BODY25 + OWN_KEYPOINTS[model]
    assert people.shape == (2, len(reader_layout(model)), 3) and (people[1] == 0).all()
    np.testing.assert_allclose(people[0, list(MODEL_JOINT_IDS)], KNOWN[list(MODEL_JOINT_IDS)])
    assert (people[0, 25:] == OWN).all()
    names = set(pose_keypoints(model))
    for joint, (a, b) in {"Neck": ("RShoulder", "LShoulder"), "MidHip": ("RHip", "LHip")}.items():
        expected = KNOWN[BODY25.index(joint)] if joint in names else midpoint(a, b)  # derived if lacking
        np.testing.assert_allclose(people[0, BODY25.index(joint)], expected)
    lacking = [j for j, n in enumerate(BODY25) if n not in names | {"Neck", "MidHip"}]
    assert (people[0, lacking] == 0).all()  # absent: the feet in COCO, nothing elsewhere
    assert len(lacking) == {"COCO": 6}.get(model, 0)


def test_a_derived_joint_needs_both_ends():
    person = in_model_order(KNOWN, "BODY_25B")
    person[KEYPOINT_MODELS["BODY_25B"].index("LHip")] = 0  # not detected
    body = to_reader_layout(person[None], "BODY_25B")[0]
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


def test_simulated_keypoints_err_as_configured_in_shuffled_order():
    """Each joint's RMS error in plain view is sigma_scale x COCO's sigma of the person's scale s (the
    twin's detector), hidden joints err more, and the people come in random order."""
    rng = np.random.default_rng(1)
    camera = make_rig(rng)[2]  # at the -y end, looking at the far (+y) player
    far_player = STANDING + [0.0, 2.4, 0.0]
    bystander = STANDING + [2.5, 1.0, 0.0]
    truths = [camera.project(far_player), camera.project(bystander)]
    _, px, depth = projected_people(camera, np.stack([far_player, bystander])[:, None])
    scale = object_scale(px)[:, 0]
    hidden = self_hidden(px, depth, camera.K[0, 0])[:, 0]
    for sigma_scale in (1.0, 2.0):
        errors = default_keypoint_errors(swap_rate=0.0, sigma_scale=sigma_scale, miss_rate=0.0)
        shares, first_is_player = [], []
        for _ in range(200):
            people = simulate_openpose(camera, [far_player, bystander], rng, errors)
            assert people.shape[1:] == (25, 3)
            which = []
            for person in people:
                detected = person[:, 2] > 0
                k = int(np.argmin([np.median(np.linalg.norm(person[detected, :2] - t[detected], axis=1))
                                   for t in truths]))
                clear = detected & ~hidden[k]
                shares.append(np.linalg.norm(person[clear, :2] - truths[k][clear], axis=1)
                              / (COCO_SIGMAS[clear] * scale[k]))
                assert (person[~detected] == 0).all()
                which.append(k)
            first_is_player.append(which[0] == 0)
        rms = np.sqrt(np.mean(np.concatenate(shares) ** 2))
        assert 0.9 * sigma_scale < rms < 1.1 * sigma_scale
        assert 0.3 < np.mean(first_is_player) < 0.7  # random order


def test_joints_behind_the_trunk_are_hidden_lost_or_unsure():
    """Seen from behind, a player's hands held in front of the chest are behind the trunk: lost at
    hidden_miss, else reported with confidences under 0.4; the shoulders are in plain view."""
    rng = np.random.default_rng(4)
    camera = make_rig(rng)[2]  # at the -y end, looking along +y
    # between the camera and the table, straight ahead of the camera, its back to it
    player = STANDING + [camera.center[0], -1.8, 0.0]
    player[[4, 7]] = player[[1]] + [[0.1, 0.35, -0.3], [-0.1, 0.35, -0.3]]  # wrists in front of the chest
    _, px, depth = projected_people(camera, player[None, None])
    hidden = self_hidden(px, depth, camera.K[0, 0])[0, 0]
    assert hidden[[4, 7]].all() and not hidden[[2, 5]].any()
    errors = default_keypoint_errors(swap_rate=0.0, miss_rate=0.0)
    people = np.stack([simulate_openpose(camera, [player], rng, errors)[0]
                       for _ in range(300)])
    wrists = people[:, [4, 7], 2]
    assert 0.4 < np.mean(wrists == 0) < 0.6  # hidden_miss 0.5
    assert (wrists[wrists > 0] <= 0.4).all() and (people[:, [2, 5], 2] >= 0.275).all()


def test_out_of_image_joints_are_zero_and_swaps_happen():
    rng = np.random.default_rng(2)
    camera = make_rig(rng)[2]
    player = STANDING + [0.0, 2.4, 0.0]
    px = camera.project(player)
    people = simulate_openpose(camera, [player], rng, default_keypoint_errors(swap_rate=1.0))
    assert len(people) == 1
    # with swap_rate 1 one limb's right and left joints trade places
    right_wrist_near_left = np.linalg.norm(people[0, 4, :2] - px[7]) < 8 or \
        np.linalg.norm(people[0, 11, :2] - px[14]) < 8 or np.linalg.norm(people[0, 24, :2] - px[21]) < 8
    assert right_wrist_near_left
    behind = simulate_openpose(camera, [player - [0.0, 10.0, 0.0]], rng,
                               default_keypoint_errors())  # behind the camera
    assert behind.shape == (0, 25, 3)


def test_frames_at_once_drop_absent_people_and_hide_the_occluded():
    rng = np.random.default_rng(3)
    camera = make_rig(rng)[2]  # at the -y end, looking along +y
    far_player = STANDING + [0.0, 2.4, 0.0]
    in_front = far_player + 0.2 * (camera.center - far_player.mean(axis=0))  # on the line of sight: covers it
    beside = far_player + [1.5, 0.0, 0.0]
    bodies = np.stack([np.stack([far_player] * 4), np.stack([in_front, beside, beside, beside])])
    bodies[1, 3] = np.nan  # the second person leaves in the last frame
    frames = simulate_openpose_frames(camera, bodies, rng, default_keypoint_errors(swap_rate=0.0))
    assert [len(f) for f in frames] == [2, 2, 2, 1]
    truths = camera.project(far_player), camera.project(in_front)

    def player_confidence(people):
        def off(p, t):  # median pixel distance of a person's detected joints to a projection
            return np.median(np.linalg.norm(p[p[:, 2] > 0, :2] - t[p[:, 2] > 0], axis=1))
        k = int(np.argmin([off(p, truths[0]) - off(p, truths[1]) for p in people]))
        return people[k][:, 2][people[k][:, 2] > 0]

    assert np.median(player_confidence(frames[0])) < 0.45  # behind the nearer person: low confidences
    assert np.median(player_confidence(frames[1])) > 0.5  # in the clear


# ---- what real tools write: empty persons, counts against the video, values, the declared model


@pytest.mark.parametrize("empty", [{}, {"person_id": [-1]}, {"pose_keypoints_2d": []},
                                   {"pose_keypoints_2d": None, "face_keypoints_2d": []}])
def test_a_person_without_keypoints_is_no_person(tmp_path, empty, caplog):
    path = tmp_path / "cam.00000.json"
    path.write_text(json.dumps({"version": 1.3, "people": [empty]}))
    assert read_keypoints_json(path).shape == (0, 25, 3)
    person = in_model_order(KNOWN, "BODY_25")
    path.write_text(json.dumps({"people": [empty, {"pose_keypoints_2d": person.ravel().tolist()}, empty]}))
    np.testing.assert_allclose(read_keypoints_json(path), [KNOWN])
    with caplog.at_level(logging.INFO):
        frames, keypoints = read_keypoints_folder(tmp_path, n_frames=1)
    assert frames.tolist() == [0] and keypoints.shape == (1, 1, 25, 3)
    assert f"{tmp_path}: 2 people without keypoints ({{}}) in 1 files read as nobody (the first in " \
           "cam.00000.json)" in caplog.text


@pytest.mark.parametrize(("name", "extra", "missing"), [
    ("cam2.{:05d}.json", "cam2.00004.json", "cam2.00004.json, cam2.00005.json"),
    ("cam2.{}.json", "cam2.4.json", "cam2.4.json, cam2.5.json"),
    ("cam2_{:012d}_keypoints.json", "cam2_000000000004_keypoints.json",
     "cam2_000000000004_keypoints.json, cam2_000000000005_keypoints.json")])
def test_the_frame_count_against_the_video_names_extra_and_missing_files(tmp_path, name, extra, missing):
    _touch_frames(tmp_path, [name.format(frame) for frame in range(5)])
    assert read_keypoints_folder(tmp_path, n_frames=5)[0].tolist() == [0, 1, 2, 3, 4]
    told = rf"{tmp_path}: 1 keypoints files past the video's last frame 3 left out: {extra}$"
    with pytest.warns(UserWarning, match=told):  # one file more than the video's frames: named, left out
        assert read_keypoints_folder(tmp_path, n_frames=4)[0].tolist() == [0, 1, 2, 3]
    (tmp_path / extra).unlink()
    told = rf"4 keypoints files .* 6 frames; expected frames 0..5, one file per frame; 2 missing: {missing}$"
    with pytest.raises(KeypointsFileError, match=told):
        read_keypoints_folder(tmp_path, n_frames=6)


def test_frames_from_one_name_the_first_missing_and_the_last_extra(tmp_path):
    _touch_frames(tmp_path, [f"take.{frame:03d}.json" for frame in range(1, 13)])
    told = r"12 keypoints files \(frames 1..12\) for a video of 12 frames.*; 1 extra: take.012.json; 1 "
    with pytest.raises(KeypointsFileError, match=told + r"missing: take.000.json$"):
        read_keypoints_folder(tmp_path, n_frames=12)
    told = r"; 12 missing: take.000.json, take.013.json, take.014.json, take.015.json, take.016.json and 7 "
    with pytest.raises(KeypointsFileError, match=told):
        read_keypoints_folder(tmp_path, n_frames=24)


def _pose_with(index: int, value) -> list:
    pose = in_model_order(KNOWN, "BODY_25").ravel().tolist()
    pose[index] = value
    return pose


@pytest.mark.parametrize(("text", "expected"), [
    ("NaN", r"keypoint 2 \(RShoulder\) has y = nan, expected a finite number"),
    ("Infinity", r"keypoint 2 \(RShoulder\) has y = inf, expected a finite number"),
    ("-1e999", r"keypoint 2 \(RShoulder\) has y = -inf, expected a finite number"),
    ("1" + "0" * 400, r"keypoint 2 \(RShoulder\) has y = inf, expected a finite number"),
    ("null", r"pose_keypoints_2d value 7 is None \(NoneType\), expected a number"),
    ('"301.5"', r"pose_keypoints_2d value 7 is '301.5' \(str\), expected a number"),
    ("true", r"pose_keypoints_2d value 7 is True \(bool\), expected a number"),
    ("[1]", r"pose_keypoints_2d value 7 is \[1\] \(list\), expected a number")])
def test_values_must_be_finite_numbers(tmp_path, text, expected):
    path = tmp_path / "cam_000000000003_keypoints.json"
    good = json.dumps({"pose_keypoints_2d": _pose_with(7, 1.0)})
    bad = json.dumps({"pose_keypoints_2d": _pose_with(7, "VALUE")}).replace('"VALUE"', text)
    path.write_text(f'{{"version":1.3,"people":[{good},{bad}]}}')
    with pytest.raises(KeypointsFileError, match=f"{path}: person 1: {expected}"):
        read_keypoints_json(path)


@pytest.mark.parametrize(("pose", "expected"), [
    (_pose_with(20, 1.5), r"person 0: keypoint 6 \(LElbow\) has confidence 1.5, expected one in \[0, 1\]"),
    (_pose_with(74, -0.1), r"person 0: keypoint 24 \(RHeel\) has confidence -0.1, expected one in \[0, 1\]"),
    (_pose_with(0, 0.0)[:-1], r"person 0 has 74 pose_keypoints_2d values, not a multiple of 3 \(x, y, "
                              r"confidence per keypoint\), expected 75 \(25 keypoints x 3\) for BODY_25$"),
    (_pose_with(0, 0.0)[:-3], r"person 0 has 72 pose_keypoints_2d values, expected 75 .* for BODY_25$"),
    ({"x": 1}, r"person 0: pose_keypoints_2d is dict, expected a list of 75 numbers")])
def test_confidences_and_lengths_are_checked(tmp_path, pose, expected):
    path = tmp_path / "cam.00001.json"
    path.write_text(json.dumps({"people": [{"pose_keypoints_2d": pose}]}))
    with pytest.raises(KeypointsFileError, match=f"{path}: {expected}"):
        read_keypoints_json(path)
    path.write_text(json.dumps({"people": [[1, 2, 3]]}))
    with pytest.raises(KeypointsFileError, match=r"person 0 is list \[1, 2, 3\], expected an object"):
        read_keypoints_json(path)
    path.write_text(json.dumps({"people": {"0": {}}}))
    with pytest.raises(KeypointsFileError, match="not an OpenPose keypoints JSON .*people is dict, not a "):
        read_keypoints_json(path)


TINY_OPENPOSE = "raw/sessions/s00/openpose/cam{}"


def as_body25b(person: np.ndarray, head: str) -> np.ndarray:
    """(25, 3) a BODY_25 person in BODY_25B's order by joint name; BODY_25B's own UpperNeck and HeadTop
    undetected (head 'absent') or placed on the neck-nose line (head 'derived') as a real model fills them."""
    out = np.array([person[BODY25.index(n)] if n in BODY25 else (0.0, 0.0, 0.0)
                    for n in KEYPOINT_MODELS["BODY_25B"]])
    neck, nose = person[BODY25.index("Neck")], person[BODY25.index("Nose")]
    if head == "derived" and neck[2] > 0 and nose[2] > 0:
        for name, along in (("UpperNeck", 0.4), ("HeadTop", 1.8)):
            out[KEYPOINT_MODELS["BODY_25B"].index(name)] = [*(neck[:2] + along * (nose[:2] - neck[:2])),
                                                            min(neck[2], nose[2])]
    return out


def write_as(folder, people_by_frame, convert) -> None:
    folder.mkdir()
    for frame, people in enumerate(people_by_frame):
        write_model_json(folder / f"cam.{frame:05d}.json", [convert(p) for p in people])


@pytest.mark.parametrize("cam", [0, 1, 2])
def test_the_twins_body25_folders_pass_the_model_check(tiny_run, cam):
    """Every person of the tiny run read as BODY_25 and as BODY_25B: the declared BODY_25 is far the
    shorter skeleton, so no error (the check's margin: the wrong reading is longer by ~2x)."""
    folder = tiny_run / TINY_OPENPOSE.format(cam)
    frames, people = read_keypoints_folder(folder)
    assert len(frames) > 1000
    n, share, ratio, _ = model_comparison(people, "BODY_25", "BODY_25B")
    assert n > 10_000 and share < 0.2 and ratio < 0.6


@pytest.mark.parametrize("head", ["absent", "derived"])
def test_a_model_of_the_same_length_declared_wrongly_is_named(tiny_run, tmp_path, head):
    """The twin's BODY_25 people written as BODY_25B: declared BODY_25 (the silent 376 mm error of the
    issue) and BODY_25 files declared BODY_25B are both refused naming a file and the likely model;
    declared rightly, both read the same joints."""
    frames, people = read_keypoints_folder(tiny_run / TINY_OPENPOSE.format(1))
    people = [p[p[:, :, 2].max(axis=1) > 0] for p in people[:300]]
    write_as(tmp_path / "b25b", people, lambda p: as_body25b(p, head))
    write_as(tmp_path / "b25", people, lambda p: p)
    with pytest.raises(KeypointsFileError, match=r"b25b/cam.\d{5}.json: keypoints declared BODY_25 look like "
                                                 r"BODY_25B: .*\(BODY_25B likely\)"):
        read_keypoints_folder(tmp_path / "b25b", "BODY_25")
    with pytest.raises(KeypointsFileError, match=r"b25/cam.\d{5}.json: keypoints declared BODY_25B look like "
                                                 r"BODY_25: .*\(BODY_25 likely\)"):
        read_keypoints_folder(tmp_path / "b25", "BODY_25B")
    _, from_b25b = read_keypoints_folder(tmp_path / "b25b", "BODY_25B")
    _, from_b25 = read_keypoints_folder(tmp_path / "b25", "BODY_25")
    joints = list(MODEL_JOINT_IDS)
    np.testing.assert_allclose(from_b25b[..., joints, :], from_b25[..., joints, :])


def _rotated(points: np.ndarray, axis: str, degrees: float, about=(0.0, 0.0, 0.0)) -> np.ndarray:
    rotation = Rotation.from_euler(axis, degrees, degrees=True)
    return rotation.apply(points - about) + about


def posed_body(pose: str) -> np.ndarray:
    """(25, 3) STANDING's joints (facing -y, feet on the floor, z up from it) in another plausible pose."""
    body = STANDING + [0.0, 0.0, 0.76]
    upper = body[:, 2] > 0.9  # above the hips
    if pose == "lying on the side":
        return _rotated(body, "y", 90) + [0.0, 0.0, 0.3]
    if pose in ("lying on the back", "lying face down"):
        return _rotated(body, "x", -90 if pose == "lying on the back" else 90) + [0.0, 0.0, 0.15]
    if pose == "bending":
        body[upper] = _rotated(body[upper], "x", 80, about=(0.0, 0.0, 0.95))
    if pose == "crouching":
        knees = [BODY25.index("RKnee"), BODY25.index("LKnee")]
        body[upper] -= [0.0, 0.0, 0.45]
        body[[BODY25.index(n) for n in ("MidHip", "RHip", "LHip")]] -= [0.0, 0.0, 0.45]
        body[knees] = body[knees] * [1, 0, 0] + [0.0, -0.4, 0.5]
    return body


def posed_people(pose: str, rng: np.random.Generator, n_frames: int = 40) -> np.ndarray:
    """(F, P, 25, 3) simulated OpenPose BODY_25 people of two people in the pose, turned every way, in
    view of one camera of the twin's rig."""
    camera = make_rig(np.random.default_rng(7))[2]  # at the -y end, looking along +y
    bodies = np.array([[_rotated(posed_body(pose), "z", rng.uniform(0, 360))
                        + [rng.uniform(-1.0, 1.0), rng.uniform(1.5, 3.0), -0.76] for _ in range(n_frames)]
                       for _ in range(2)])
    frames = simulate_openpose_frames(camera, bodies, rng, default_keypoint_errors())
    out = np.zeros((n_frames, 2, 25, 3))
    for f, people in enumerate(frames):
        out[f, :len(people)] = people
    return out


@pytest.mark.parametrize("pose", ["standing", "lying on the side", "lying on the back", "lying face down",
                                  "bending", "crouching"])
def test_people_lying_or_bending_pass_and_a_wrong_model_is_still_named(pose):
    people = posed_people(pose, np.random.default_rng(11))
    as_b25b = np.array([[as_body25b(p, "derived") for p in frame] for frame in people])
    paths = [Path(f"cam.{f:05d}.json") for f in range(len(people))]
    for raw, model, other in ((people, "BODY_25", "BODY_25B"), (as_b25b, "BODY_25B", "BODY_25")):
        n, share, ratio, _ = model_comparison(raw, model, other)
        assert n >= 60 and share < 0.3 and ratio < 0.8  # the declared model's skeleton the shorter
        check_declared_model(raw, model, paths)
        told = rf"cam.\d{{5}}.json: keypoints declared {other} look like {model}"
        with pytest.raises(KeypointsFileError, match=told):
            check_declared_model(raw, other, paths)


# COCO with MMPose's keypoint order and a neck added: 18 keypoints as OpenPose's COCO, in another order
COCO_OTHER_ORDER = ("Nose", "Neck", "LEye", "REye", "LEar", "REar", "LShoulder", "RShoulder", "LElbow",
                    "RElbow", "LWrist", "RWrist", "LHip", "RHip", "LKnee", "RKnee", "LAnkle", "RAnkle")


@pytest.mark.parametrize("model", ["COCO", "HALPE_26"])
def test_coco_and_halpe_pass_and_a_model_of_their_length_is_told_apart(model, monkeypatch):
    """No two registered models but BODY_25 and BODY_25B share a keypoint count, so COCO and HALPE_26 meet
    only the count check; a model of the same count in another order (here registered for the test) is
    told apart by the same skeleton lengths."""
    people = posed_people("standing", np.random.default_rng(12))
    raw = np.array([[in_model_order(p, model) for p in frame] for frame in people])
    raw[..., 2] *= (people[..., 2] > 0).any(axis=-1)[..., None]  # absent people stay all zeros
    paths = [Path(f"cam.{f:05d}.json") for f in range(len(people))]
    check_declared_model(raw, model, paths)
    assert sum(len(names) == len(KEYPOINT_MODELS[model]) for names in KEYPOINT_MODELS.values()) == 1
    names = KEYPOINT_MODELS[model]
    other = COCO_OTHER_ORDER if model == "COCO" else names[16::-1] + names[17:]  # Halpe's first 17 reversed
    monkeypatch.setitem(KEYPOINT_MODELS, "OTHER", other)
    with pytest.raises(KeypointsFileError, match=rf"declared OTHER look like {model}: .*\({model} likely\)"):
        check_declared_model(raw, "OTHER", paths)
    check_declared_model(raw, model, paths)


def test_a_folder_of_few_people_is_not_judged():
    people = posed_people("standing", np.random.default_rng(13), n_frames=4)[:, :1]
    assert 0 < (people[..., 2] > 0).any(axis=-1).sum() < MIN_PEOPLE
    check_declared_model(people, "BODY_25B", [Path(f"cam.{f}.json") for f in range(len(people))])


# Issue 48: a held-out fuzz run's findings, each now a KeypointsFileError naming the file


@pytest.mark.parametrize("deep", ['{"people": ' + "[" * 200_000 + "]" * 200_000 + "}",
                                  "[" * 200_000, '{"people": [{"pose_keypoints_2d": ' + '{"x": ' * 200_000])
def test_json_nested_too_deep_is_named(tmp_path, deep):
    """JSON nested 200,000 deep (whole, or cut short) raised json's RecursionError naming no file."""
    path = tmp_path / "cam_000000000003_keypoints.json"
    path.write_text(deep)
    with pytest.raises(KeypointsFileError, match=rf"{path}: not an OpenPose keypoints JSON \(nested deeper "
                                                 r"than the parser recurses\); expected \{\"version\""):
        read_keypoints_json(path)


def test_a_frame_number_beyond_int64_is_named(tmp_path):
    """A dotted layout's frame number of any digit count: 20 digits became an OverflowError naming no file."""
    for frame in (0, 10**20):
        (tmp_path / f"cam.{frame}.json").write_text('{"people": []}')
    with pytest.raises(KeypointsFileError, match=rf"cam\.{10**20}\.json: frame number {10**20} does not fit "
                                                 "int64; expected a frame number"):
        read_keypoints_folder(tmp_path)
