"""The robot's episodes as Foxglove scenes and the simulation figure, on a synthetic hit: the MCAP holds only
Foxglove schemas, its ball is the episode's ball, its paddle the Pinocchio paddle of the simulated robot,
the opponent shows while the input sequence has joints; the figure is a real image."""

from types import SimpleNamespace

import cv2
import numpy as np
import pandas as pd
import pytest
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory
from scipy.spatial.transform import Rotation
from workflow_util import ROBOT_LIMITS, ROBOT_URDF

from pingpong.frames import FRAME_NS, N_INPUT, STRIKE_Y
from pingpong.robot.controllers import Controller
from pingpong.robot.episode import EpisodeParams
from pingpong.robot.evaluate import Prediction, SimSettings, simulate_hit
from pingpong.robot.flights import HitFlight, hit_flight
from pingpong.robot.model import PADDLE_RADIUS, frame_pose, load_robot
from pingpong.robot.scene import (
    TOPICS,
    check_against_sim,
    episode_scene,
    robot_visuals,
    scene_hits,
    write_scene_mcap,
)
from pingpong.robot.scene_figure import plot_scenes

ROBOT = load_robot(ROBOT_URDF, ROBOT_LIMITS)
VISUALS = robot_visuals(ROBOT)
CAMERA_NS = 1_700_000_000_000_000_000 + FRAME_NS * np.arange(150)  # the session's camera clock
HIT_FRAME = 50
N_FRAMES = 40
FRAMES = np.arange(-30, 1)
CONTROLLER = Controller("anticipatory", 1.0, 1.0)  # moves before the hit, so the paddle path is not trivial
# the paper's timing and its quadratic servo fit, which is exact on the straight gravity-free flight below
# (the model fit assumes gravity, drag and lift)
SETTINGS = SimSettings(EpisodeParams(servo_fit="paper"))


def synthetic_hit(offset_ns: int, strike_x: float = 0.45):
    """(DATASET-like row, flight) of a 'near' hit offset_ns after its hit frame: a ball flying straight to
    (strike_x, STRIKE_Y, 0.25) in 0.6 s with one frame unseen, and 40 input frames of a swaying opponent."""
    t_hit = int(CAMERA_NS[HIT_FRAME]) + offset_ns
    t = (CAMERA_NS - t_hit) / 1e9
    start, end = np.array([0.1, 1.5, 0.3]), np.array([strike_x, STRIKE_Y, 0.25])
    ball = start + np.clip(t, 0, None)[:, None] / 0.6 * (end - start)
    ball[t < 0] = np.nan
    ball[HIT_FRAME + 5] = np.nan  # a frame without a ball
    table = pd.DataFrame({"time_ns": CAMERA_NS, "x": ball[:, 0], "y": ball[:, 1], "z": ball[:, 2]})
    flight = HitFlight(*hit_flight(table, t_hit, "near"), *hit_flight(table, t_hit, "near"))
    k = np.arange(N_FRAMES)
    x = np.zeros((N_FRAMES, N_INPUT))
    joints = np.array([[0.2, 1.9, 0.6], [0.4, 1.8, 0.4], [0.5, 1.6, 0.3], [-0.2, 1.9, 0.6],
                       [-0.3, 1.9, 0.35], [-0.3, 1.8, 0.15], [0.15, 1.95, 0.0], [-0.15, 1.95, 0.0]])
    x[:, :24] = (joints[None] + 0.01 * k[:, None, None] * np.array([1.0, 0, 0])).reshape(N_FRAMES, 24)
    x[:, 24:27] = [0.5, 1.5, 0.3]
    x[:, 27:36] = np.eye(3).ravel()
    x[:, 36:39] = np.column_stack([0.1 - 0.01 * k[::-1], 1.5 - 0.05 * k[::-1], 0.3 + 0 * k])  # incoming
    hit = SimpleNamespace(session="s00", rally=3, hit=7, hitter="near", t_hit_ns=t_hit, hit_frame=HIT_FRAME,
                          n_frames=N_FRAMES, x=x.ravel().tolist(), region="right")
    return hit, flight


def make_scene(offset_ns: int = 0, strike_x: float = 0.45):
    hit, flight = synthetic_hit(offset_ns, strike_x)
    prediction = Prediction(FRAMES, np.full(len(FRAMES), strike_x))
    labels = np.tile([0.0, -0.2, strike_x + 0.2 * STRIKE_Y], (len(FRAMES), 1))  # passes the predicted point
    return episode_scene(ROBOT, hit, CAMERA_NS, flight, prediction, labels, CONTROLLER, SETTINGS), hit, flight


def read_scene(path):
    """({topic: schema name}, metadata {name: dict}, [(topic, log_time, decoded message)])."""
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        schemas = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        messages = [(c.topic, m.log_time, d)
                    for _, c, m, d in reader.iter_decoded_messages(log_time_order=True)]
    return schemas, metadata, messages


def entity(message, entity_id):
    found = [e for e in message.entities if e.id == entity_id]
    return found[0] if found else None


def xyz(pose) -> np.ndarray:
    return np.array([pose.position.x, pose.position.y, pose.position.z])


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory):
    scene, hit, flight = make_scene()
    path = tmp_path_factory.mktemp("scene") / "anticipatory_test0.mcap"
    write_scene_mcap(path, scene, ROBOT, VISUALS, {"pingpong": {"stage": "test"}})
    return scene, hit, flight, read_scene(path)


def test_scene_mcap_holds_foxglove_channels_on_the_camera_clock(scene_file):
    scene, hit, _, (schemas, metadata, messages) = scene_file
    assert set(schemas) == set(TOPICS)
    assert set(schemas.values()) == {"foxglove.SceneUpdate", "foxglove.FrameTransforms"}
    assert schemas["/tf"] == "foxglove.FrameTransforms"
    assert metadata["episode"]["controller"] == "anticipatory" and metadata["episode"]["hit"] == "7"
    assert metadata["pingpong"] == {"stage": "test"}
    log_times = sorted({t for _, t, _ in messages})
    # every camera frame from the input sequence's first to past the strike, each with every topic
    assert log_times[0] == CAMERA_NS[HIT_FRAME - N_FRAMES + 1]
    assert np.all(np.diff(log_times) == FRAME_NS) and set(log_times) <= set(CAMERA_NS)
    assert len(messages) == len(TOPICS) * len(log_times)
    assert (log_times[-1] - hit.t_hit_ns) / 1e9 >= scene.t_strike
    for topic, log_time, message in messages:
        if topic == "/tf":
            assert {t.parent_frame_id for t in message.transforms} == {"table"}
            continue
        assert [d.type for d in message.deletions] == [1]  # ALL: each message is its topic's whole state
        for e in message.entities:
            assert e.id and e.frame_id == "table" and e.timestamp.ToNanoseconds() == log_time


def test_scene_ball_is_the_episodes_ball(scene_file):
    _, hit, flight, (_, _, messages) = scene_file
    times, positions = flight.times, flight.positions
    balls = {t: entity(m, "ball") for topic, t, m in messages if topic == "/ball"}
    flight_ns = hit.t_hit_ns + np.rint(times * 1e9).astype(np.int64)
    for t, p in zip(flight_ns, positions, strict=True):
        assert np.allclose(xyz(balls[t].spheres[0].pose), p, atol=1e-12)
    assert balls[int(CAMERA_NS[HIT_FRAME + 5])] is None  # the unseen frame has no ball
    inputs = np.asarray(hit.x).reshape(N_FRAMES, N_INPUT)
    first = int(CAMERA_NS[HIT_FRAME - N_FRAMES + 1])
    assert np.allclose(xyz(balls[first].spheres[0].pose), inputs[0, 36:39])  # before the hit: the input's


def test_scene_paddle_is_the_simulated_robots_pinocchio_paddle(scene_file):
    """The hit falls on a frame here, so the frames are the control steps (10 ms from -0.1 s)."""
    _, hit, flight, (_, _, messages) = scene_file
    out = simulate_hit(ROBOT, flight, Prediction(FRAMES, np.full(len(FRAMES), 0.45)), CONTROLLER, SETTINGS)
    robot = {(t - hit.t_hit_ns) / 1e9: m for topic, t, m in messages if topic == "/robot"}
    checked = 0
    for t, q, paddle in zip(out["times"], out["q"], out["paddle"], strict=True):
        message = robot.get(round(t, 9))
        if message is None:
            continue
        disc = entity(message, "paddle").cylinders[0]
        position, rotation = frame_pose(ROBOT, q)
        assert np.allclose(xyz(disc.pose), position, atol=1e-9) and np.allclose(position, paddle, atol=1e-9)
        o = disc.pose.orientation
        assert np.allclose(Rotation.from_quat([o.x, o.y, o.z, o.w]).as_matrix(), rotation, atol=1e-9)
        assert np.allclose([disc.size.x, disc.size.y], 2 * PADDLE_RADIUS)
        checked += 1
    assert checked == len(out["times"])
    assert out["hit"]  # anticipation on a perfect prediction: the scene shows a hit
    assert np.ptp(out["paddle"][:, 0]) > 0.2  # and the paddle moved to it


def test_opponent_shows_while_the_input_has_joints(scene_file):
    _, hit, _, (_, _, messages) = scene_file
    inputs = np.asarray(hit.x).reshape(N_FRAMES, N_INPUT)
    opponent = [(t, m) for topic, t, m in messages if topic == "/opponent"]
    for t, message in opponent:
        skeleton = entity(message, "skeleton")
        if t > CAMERA_NS[HIT_FRAME]:
            assert skeleton is None and not message.entities
            continue
        k = np.flatnonzero(CAMERA_NS == t)[0] - (HIT_FRAME - N_FRAMES + 1)
        joints = np.array([xyz(s.pose) for s in skeleton.spheres])
        assert np.allclose(joints, inputs[k, :24].reshape(8, 3))
        assert len(skeleton.lines[0].points) == 16  # 8 bones
        assert np.allclose(xyz(entity(message, "opponent_paddle").cylinders[0].pose), inputs[k, 24:27])


def test_a_hit_between_frames_keeps_the_camera_clock_and_the_flight():
    scene, hit, flight = make_scene(offset_ns=3_700_000)
    times, positions = flight.times, flight.positions
    assert set(scene.log_times) <= set(CAMERA_NS)
    assert np.allclose(scene.times, (scene.log_times - hit.t_hit_ns) / 1e9)
    flight_ns = hit.t_hit_ns + np.rint(times * 1e9).astype(np.int64)
    index = np.searchsorted(scene.log_times, flight_ns)
    assert np.array_equal(scene.log_times[index], flight_ns) and np.allclose(scene.ball[index], positions)


def test_check_against_sim_and_scene_hits_fail_clearly():
    scene, _, _ = make_scene()
    info = scene.info
    sim = pd.DataFrame([{"session": "s00", "rally": 3, "hit": 7, "hit_ball": info["hit_ball"],
                         "end_distance_m": info["end_distance_m"]}])
    check_against_sim(scene, sim, "sim.parquet")
    with pytest.raises(ValueError, match="sim.parquet.*differ from simulate_robot"):
        check_against_sim(scene, sim.assign(end_distance_m=info["end_distance_m"] + 0.01), "sim.parquet")
    dataset = pd.DataFrame({"split": ["train", "test", "test", "calibration"], "hit": [0, 1, 2, 3]})
    assert list(scene_hits(dataset, 2)["hit"]) == [1, 2]
    with pytest.raises(ValueError, match="robot.scene_hits is 3.*2 test hits"):
        scene_hits(dataset, 3)


def test_simulation_figure_is_a_real_image(tmp_path):
    scenes = [make_scene(strike_x=x)[0] for x in (0.45, -0.3)]
    scenes[1].info.update(hit=8, controller="anticipatory")  # a second row
    path = tmp_path / "robot_scene.png"
    plot_scenes(scenes, ROBOT, VISUALS, path)
    image = cv2.imread(str(path))
    assert image is not None and image.shape[0] > 500 and image.shape[1] > 300
    assert image.std() > 20  # drew something, not a blank canvas
    table_blue = np.abs(image.astype(int) - [133, 61, 26]).sum(axis=2) < 30  # BGR
    assert table_blue.mean() > 0.01
