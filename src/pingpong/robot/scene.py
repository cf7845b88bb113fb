"""One simulated episode as a 3D scene: what the robot saw, predicted and did, frame by frame, written as an
MCAP file that Foxglove opens as it is.

An episode is one test hit under one controller, re-run with the same functions simulate_robot uses
(flights.hit_flight, evaluate.hit_predictions and simulate_hit), so the robot moves exactly as in
processed/sim/{controller}.parquet (check_against_sim says so or raises).

Scene frames: the session's camera frames (100 Hz) from the first frame of the hit's input sequence to
the last sample of its post-hit flight (one past the strike line) or the robot's last step, whichever is
later. A frame's log_time in the MCAP is its camera timestamp (the filtered ball table's time_ns, the
camera streams' log_time), so the scene plays beside the session's recordings; t = log_time - t_hit_ns
is the episode's clock (the hit falls between frames). Frame id "table" is the dataset's frame: the table
frame (docs/architecture.md), mirrored for a 'far' hitter (curation.labels) so that the ball always flies
towards the robot at -y.
  - ball: the post-hit flight where a sample falls on the frame, else (up to the hit) the input
    sequence's ball; NaN where neither has one. The observed path is every ball seen up to the frame.
  - the opponent (the hitter): the 8 joints and the paddle of the input sequence, which ends at the hit,
    so the skeleton disappears after the hit frame.
  - predictions: the model's latest prediction computed at or before the frame (a1, a2, b and strike x;
    its height is the controller's anticipation height), and the goal the robot is moving to.
  - robot: the configuration interpolated between control steps (on the hit's clock, so up to a frame
    apart from the camera frames), held at its first value before the episode starts (the robot rests at
    home) and at its last after it ends.
"""

from dataclasses import dataclass

import numpy as np
import pandas as pd
import pinocchio as pin
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.Point3_pb2 import Point3
from foxglove_schemas_protobuf.Pose_pb2 import Pose
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneEntityDeletion_pb2 import SceneEntityDeletion
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from scipy.spatial.transform import Rotation

from pingpong.curation.labels import BALL, PADDLE_POSITION, PADDLE_ROTATION
from pingpong.frames import (
    BALL_RADIUS,
    MODEL_BONES,
    MODEL_JOINTS,
    N_INPUT,
    NET_HEIGHT,
    NET_OVERHANG,
    STRIKE_Y,
    TABLE_HALF_LENGTH,
    TABLE_HALF_WIDTH,
)
from pingpong.io.mcap_io import SceneWriter
from pingpong.robot.controllers import Controller
from pingpong.robot.evaluate import Prediction, SimSettings, sim_settings, simulate_hit
from pingpong.robot.flights import HitFlight, prediction_series
from pingpong.robot.model import PADDLE_RADIUS, Robot
from pingpong.robot.regimes import Regime
from pingpong.twin.ball import BallParams

FRAME_ID = "table"
TOPICS = ("/table", "/ball", "/prediction", "/robot", "/opponent", "/tf")
# the frames the arm's links are drawn through, base to paddle (the iiwa has no visuals in the URDF)
ARM_FRAMES = ("iiwa_link_0", *(f"iiwa_link_{i}" for i in range(1, 8)), "flange", "paddle")
# bones between MODEL_JOINTS (RShoulder, RElbow, RWrist, LShoulder, LElbow, LWrist, RHip, LHip)
TABLE_THICKNESS = 0.025  # m, the top only (legs are not drawn)
LINK_THICKNESS = 0.10  # m, the iiwa's links are 10-15 cm across
PADDLE_THICKNESS = 0.01  # m, as the URDF's paddle disc


@dataclass(frozen=True)
class SceneEpisode:
    """Everything a scene shows, per frame (F frames); positions in the (mirrored) table frame, m."""

    info: dict  # session, rally, hit, hitter, t_hit_ns, region, controller, hit_ball, end_distance_m
    log_times: np.ndarray  # (F,) int64 ns, the camera frames' times
    times: np.ndarray  # (F,) s from the hit (the episode's clock)
    ball: np.ndarray  # (F, 3), NaN where no ball was seen
    q: np.ndarray  # (F, 9) robot configuration
    goal: np.ndarray  # (F, 2) (x, z) on the strike line the robot moves to; NaN while it has none
    joints: np.ndarray  # (F, 8, 3) the opponent's joints; NaN after the hit
    opponent_paddle: np.ndarray  # (F, 3); NaN after the hit
    opponent_paddle_rotation: np.ndarray  # (F, 3, 3); NaN after the hit
    labels: np.ndarray  # (F, 3) a1, a2, b of the latest model prediction; NaN before the first
    predicted_strike: np.ndarray  # (F, 2) (x, z) of that prediction
    ball_strike: np.ndarray  # (3,) where the ball crosses the strike line; NaN if it never does
    t_strike: float  # s, when it does
    paddle_strike: np.ndarray  # (3,) the paddle centre then


# ---------------------------------------------------------------- the episode

def scene_hits(dataset: pd.DataFrame, n_hits: int) -> pd.DataFrame:
    """The first n_hits test hits of a DATASET table, in its order (config robot.scene_hits)."""
    test = dataset[dataset["split"] == "test"].reset_index(drop=True)
    if len(test) < n_hits:
        raise ValueError(f"robot.scene_hits is {n_hits}, but the dataset has {len(test)} test hits: "
                         "lower it in the config")
    return test.head(n_hits)


def prediction_labels(predictions: pd.DataFrame, hits: pd.DataFrame) -> list[np.ndarray]:
    """Per hit (rows of `hits`): the predicted labels (P, 3) a1, a2, b at its prediction frames, in the order
    of evaluate.hit_predictions (predictions: one model's PREDICTIONS rows)."""
    series = [prediction_series(predictions, hits, column) for column in ("a1", "a2", "b")]
    return [np.column_stack([labels[k][1] for labels in series]) for k in range(len(hits))]


def input_frames(hit) -> np.ndarray:
    """A DATASET row's input sequence as (n_frames, 39); its last frame is the hit (frame 0)."""
    return np.asarray(hit.x, float).reshape(int(hit.n_frames), N_INPUT)


def _latest(sorted_frames: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """Index of the last of sorted_frames at or before each frame; -1 where none is."""
    return np.searchsorted(sorted_frames, frames, side="right") - 1


def _take(values: np.ndarray, index: np.ndarray) -> np.ndarray:
    """values[index] with NaN rows where index is -1."""
    if len(values) == 0:
        return np.full((len(index), *values.shape[1:]), np.nan)
    out = values[np.maximum(index, 0)].astype(float)
    out[index < 0] = np.nan
    return out


def episode_scene(robot: Robot, hit, camera_ns: np.ndarray, flight: HitFlight,
                  prediction: Prediction, labels: np.ndarray, controller: Controller,
                  settings: SimSettings) -> SceneEpisode:
    """Re-run one hit's episode and lay it out on the camera frames.

    hit: a DATASET row (with 'x'); camera_ns: the session's frame times (the filtered ball table's time_ns,
    which hit_frame indexes); flight: its flights.HitFlight (the judged flight is shown); prediction: its
    hit_predictions entry; labels (P, 3): a1, a2, b at prediction.frames.
    """
    times, positions = flight.times, flight.positions
    out = simulate_hit(robot, flight, prediction, controller, settings)
    inputs = input_frames(hit)
    t_hit, hit_frame, camera_ns = int(hit.t_hit_ns), int(hit.hit_frame), np.asarray(camera_ns, np.int64)
    # the flight's samples are camera frames: back to their indices (exact: times came from these ns)
    flight_index = np.searchsorted(camera_ns, t_hit + np.rint(np.asarray(times) * 1e9).astype(np.int64))
    robot_end = np.searchsorted(camera_ns, t_hit + int(np.ceil(out["times"][-1] * 1e9)))
    last = min(max(int(flight_index.max(initial=hit_frame)), int(robot_end)), len(camera_ns) - 1)
    index = np.arange(hit_frame - len(inputs) + 1, last + 1)
    pre = index <= hit_frame  # frames the input sequence holds
    k_input = index[pre] - index[0]

    ball = np.full((len(index), 3), np.nan)
    ball[pre] = inputs[k_input, BALL]
    ball[flight_index - index[0]] = positions  # the measured flight wins where both have the ball
    joints = np.full((len(index), len(MODEL_JOINTS), 3), np.nan)
    joints[pre] = inputs[k_input, :3 * len(MODEL_JOINTS)].reshape(-1, len(MODEL_JOINTS), 3)
    paddle = np.full((len(index), 3), np.nan)
    paddle[pre] = inputs[k_input, PADDLE_POSITION]
    rotation = np.full((len(index), 3, 3), np.nan)
    rotation[pre] = inputs[k_input, PADDLE_ROTATION].reshape(-1, 3, 3)

    log_times = camera_ns[index]
    t = (log_times - t_hit) / 1e9
    q = np.column_stack([np.interp(t, out["times"], out["q"][:, j]) for j in range(out["q"].shape[1])])
    step = _latest(out["times"], t + 1e-9)
    latest = _latest(hit_frame + prediction.frames, index)  # shown from the frame it was computed at
    heights = np.full(len(prediction.frames), settings.anticipation_z)
    predicted = np.column_stack([prediction.strike_x, heights])
    info = {"session": hit.session, "rally": int(hit.rally), "hit": int(hit.hit), "hitter": hit.hitter,
            "t_hit_ns": t_hit, "region": hit.region, "controller": controller.name,
            "hit_ball": out["hit"], "end_distance_m": out["end_distance_m"]}
    return SceneEpisode(info, log_times, t, ball, q, _take(out["goal"], step), joints, paddle, rotation,
                        _take(np.asarray(labels, float).reshape(-1, 3), latest),
                        _take(predicted, latest), out["ball_strike"], out["strike_time_s"],
                        out["paddle_strike"])


def controller_scenes(robot: Robot, hits: pd.DataFrame, camera_ns: dict[str, np.ndarray], flights: list,
                      predictions: list[Prediction], labels: list[np.ndarray], choice: dict,
                      regime: Regime, servo_ball: BallParams | None = None) -> list[SceneEpisode]:
    """episode_scene of every row of `hits` under the controller of a processed/sim/{controller}.json
    (choice); camera_ns: each session's frame times; regime, servo_ball: as simulate_robot ran it."""
    controller = Controller.from_choice(choice)
    sim = sim_settings(regime, choice["anticipation_z_m"], servo_ball)
    return [episode_scene(robot, hit, camera_ns[hit.session], flights[k], predictions[k], labels[k],
                          controller, sim) for k, hit in enumerate(hits.itertuples(index=False))]


def check_against_sim(scene: SceneEpisode, sim: pd.DataFrame, path) -> None:
    """Raise if the re-run episode is not the one in the SIM table (simulate_robot's output at `path`)."""
    info = scene.info
    rows = sim[(sim["session"] == info["session"]) & (sim["rally"] == info["rally"])
               & (sim["hit"] == info["hit"])]
    if len(rows) != 1:
        raise ValueError(f"{path}: {len(rows)} rows for hit {info['session']}/{info['rally']}/{info['hit']}, "
                         "expected 1")
    row = rows.iloc[0]
    same_distance = np.isclose(row["end_distance_m"], info["end_distance_m"], rtol=0, atol=1e-9,
                               equal_nan=True)
    if bool(row["hit_ball"]) != info["hit_ball"] or not same_distance:
        raise ValueError(f"{path}: hit {info['session']}/{info['rally']}/{info['hit']} re-run under "
                         f"{info['controller']} ends {info['end_distance_m']} m from the ball (hit "
                         f"{info['hit_ball']}), the table says {row['end_distance_m']} m (hit "
                         f"{row['hit_ball']}): the scene's settings differ from simulate_robot's")


# ---------------------------------------------------------------- the robot's geometry

def robot_visuals(robot: Robot) -> pin.GeometryModel:
    """The URDF's visual shapes (the Ridgeback's box, the paddle's disc) on the robot's model."""
    return pin.buildGeomFromUrdf(robot.model, robot.urdf_path, pin.GeometryType.VISUAL)


def robot_pose(robot: Robot, visuals: pin.GeometryModel, q: np.ndarray) -> dict:
    """Forward kinematics at q: 'frames' {name: SE3} of ARM_FRAMES and 'visuals' [(name, shape, SE3)]."""
    pin.forwardKinematics(robot.model, robot.data, q)
    pin.updateFramePlacements(robot.model, robot.data)
    frames = {name: robot.data.oMf[robot.model.getFrameId(name)].copy() for name in ARM_FRAMES}
    data = visuals.createData()
    pin.updateGeometryPlacements(robot.model, robot.data, visuals, data)
    shapes = [(g.name.rsplit("_", 1)[0], g.geometry, data.oMg[i].copy())
              for i, g in enumerate(visuals.geometryObjects)]
    return {"frames": frames, "visuals": shapes}


def shape_size(shape) -> np.ndarray:
    """Full extent (3,) m of a box or of a cylinder along its z axis (Foxglove's cube and cylinder size)."""
    if hasattr(shape, "halfSide"):
        return 2.0 * np.asarray(shape.halfSide, float)
    return np.array([2 * shape.radius, 2 * shape.radius, 2 * shape.halfLength])


def arm_points(pose: dict) -> np.ndarray:
    """(K, 3) the arm drawn as a polyline: from the deck below its base, through ARM_FRAMES' origins."""
    points = np.array([pose["frames"][name].translation for name in ARM_FRAMES])
    deck = [placement.translation[2] + shape_size(shape)[2] / 2 for name, shape, placement in pose["visuals"]
            if hasattr(shape, "halfSide")]  # the base's box: the arm's riser stands on its top
    if deck:
        points = np.vstack([[points[0, 0], points[0, 1], max(deck)], points])
    return points


# ---------------------------------------------------------------- Foxglove messages

def _color(r: float, g: float, b: float, a: float = 1.0) -> Color:
    return Color(r=r, g=g, b=b, a=a)


BLUE_TABLE, WHITE, NET_GREY = _color(0.10, 0.24, 0.52), _color(1, 1, 1), _color(0.85, 0.85, 0.85, 0.6)
ORANGE, PURPLE, GREEN = _color(1.0, 0.55, 0.0), _color(0.55, 0.2, 0.8), _color(0.1, 0.7, 0.3)
KUKA_ORANGE, STEEL, PADDLE_RED = _color(0.95, 0.45, 0.1), _color(0.45, 0.45, 0.5), _color(0.8, 0.1, 0.1)
OPPONENT = _color(0.15, 0.45, 0.9)
STRIKE_PLANE = _color(0.1, 0.7, 0.3, 0.08)


def _pose(position, rotation=None) -> Pose:
    pose = Pose()
    pose.position.x, pose.position.y, pose.position.z = map(float, position)
    x, y, z, w = (0.0, 0.0, 0.0, 1.0) if rotation is None else Rotation.from_matrix(rotation).as_quat()
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = x, y, z, w
    return pose


def _vector(message, values) -> None:
    message.x, message.y, message.z = map(float, values)


def _points(points) -> list[Point3]:
    return [Point3(x=float(p[0]), y=float(p[1]), z=float(p[2])) for p in points]


def _entity(entity_id: str, log_time: int) -> SceneEntity:
    entity = SceneEntity(id=entity_id, frame_id=FRAME_ID)
    entity.timestamp.FromNanoseconds(int(log_time))
    return entity


def _sphere(entity: SceneEntity, position, diameter: float, color: Color) -> None:
    sphere = entity.spheres.add(pose=_pose(position), color=color)
    _vector(sphere.size, [diameter] * 3)


def _cube(entity: SceneEntity, position, size, color: Color, rotation=None) -> None:
    cube = entity.cubes.add(pose=_pose(position, rotation), color=color)
    _vector(cube.size, size)


def _line(entity: SceneEntity, points, thickness: float, color: Color,
          kind=LinePrimitive.LINE_STRIP) -> None:
    entity.lines.add(type=kind, pose=_pose((0, 0, 0)), thickness=thickness, scale_invariant=False,
                     points=_points(points), color=color)


def _update(log_time: int, entities=()) -> SceneUpdate:
    """A SceneUpdate that first deletes every older entity of its topic: each message is the topic's whole
    state, so Foxglove shows the right scene after a seek (it replays the latest message per topic)."""
    update = SceneUpdate(entities=list(entities))
    update.deletions.add(type=SceneEntityDeletion.ALL).timestamp.FromNanoseconds(int(log_time))
    return update


def table_update(log_time: int) -> SceneUpdate:
    """The table top with its white lines, the net and the strike plane (y = STRIKE_Y)."""
    table = _entity("table", log_time)
    _cube(table, (0, 0, -TABLE_THICKNESS / 2), (2 * TABLE_HALF_WIDTH, 2 * TABLE_HALF_LENGTH, TABLE_THICKNESS),
          BLUE_TABLE)
    w, h, z = TABLE_HALF_WIDTH, TABLE_HALF_LENGTH, 0.001
    corners = [(-w, -h, z), (w, -h, z), (w, h, z), (-w, h, z)]
    _line(table, corners, 0.02, WHITE, LinePrimitive.LINE_LOOP)
    _line(table, [(0, -h, z), (0, h, z)], 0.003, WHITE)  # the centre line
    net = _entity("net", log_time)
    _cube(net, (0, 0, NET_HEIGHT / 2), (2 * (w + NET_OVERHANG), 0.005, NET_HEIGHT), NET_GREY)
    plane = _entity("strike_plane", log_time)
    _cube(plane, (0, STRIKE_Y, 0.4), (2.4, 0.001, 0.8), STRIKE_PLANE)
    return _update(log_time, [table, net, plane])


def ball_update(scene: SceneEpisode, i: int, log_time: int) -> SceneUpdate:
    """The ball at frame i, the path seen so far and, once it has crossed, its strike point."""
    update = _update(log_time)
    if np.all(np.isfinite(scene.ball[i])):
        ball = _entity("ball", log_time)
        _sphere(ball, scene.ball[i], 2 * BALL_RADIUS, ORANGE)
        update.entities.append(ball)
    seen = scene.ball[: i + 1][np.isfinite(scene.ball[: i + 1]).all(axis=1)]
    if len(seen) >= 2:
        path = _entity("ball_path", log_time)
        _line(path, seen, 0.008, ORANGE)
        update.entities.append(path)
    if np.isfinite(scene.t_strike) and scene.times[i] >= scene.t_strike:
        strike = _entity("ball_strike", log_time)
        _sphere(strike, scene.ball_strike, 2 * BALL_RADIUS, _color(1.0, 0.85, 0.0))
        update.entities.append(strike)
    return update


def predicted_path(labels: np.ndarray, y_start: float = TABLE_HALF_LENGTH, z: float = 0.002) -> np.ndarray:
    """(3, 3) the path x(y) = a1 y + b (y >= 0), a2 y + b (y < 0) on the table, hitter to strike line."""
    a1, a2, b = labels
    return np.array([(a1 * y_start + b, y_start, z), (b, 0.0, z), (a2 * STRIKE_Y + b, STRIKE_Y, z)])


def prediction_update(scene: SceneEpisode, i: int, log_time: int) -> SceneUpdate:
    """The latest predicted path and strike point, and the goal the robot is moving to."""
    update = _update(log_time)
    if np.all(np.isfinite(scene.labels[i])):
        path = _entity("predicted_path", log_time)
        _line(path, predicted_path(scene.labels[i]), 0.012, PURPLE)
        _sphere(path, (scene.predicted_strike[i, 0], STRIKE_Y, scene.predicted_strike[i, 1]), 0.06, PURPLE)
        update.entities.append(path)
    if np.all(np.isfinite(scene.goal[i])):
        goal = _entity("goal", log_time)
        _sphere(goal, (scene.goal[i, 0], STRIKE_Y, scene.goal[i, 1]), 0.05, GREEN)
        update.entities.append(goal)
    return update


def robot_update(pose: dict, log_time: int) -> SceneUpdate:
    """The base and the paddle from the URDF's visuals, the arm's links as a thick polyline with joints."""
    update = _update(log_time)
    for name, shape, placement in pose["visuals"]:
        entity = _entity(name, log_time)
        size = shape_size(shape)
        if hasattr(shape, "halfSide"):
            _cube(entity, placement.translation, size, STEEL, placement.rotation)
        else:
            cylinder = entity.cylinders.add(pose=_pose(placement.translation, placement.rotation),
                                            bottom_scale=1.0, top_scale=1.0,
                                            color=PADDLE_RED if name == "paddle" else STEEL)
            _vector(cylinder.size, size)
        update.entities.append(entity)
    links = _entity("links", log_time)
    _line(links, arm_points(pose), LINK_THICKNESS, KUKA_ORANGE)
    for name in ARM_FRAMES[1:8]:
        _sphere(links, pose["frames"][name].translation, 1.3 * LINK_THICKNESS, STEEL)
    update.entities.append(links)
    return update


def opponent_update(scene: SceneEpisode, i: int, log_time: int) -> SceneUpdate:
    """The hitter's skeleton and paddle while the input sequence has them; deleted after the hit."""
    update = _update(log_time)
    joints = scene.joints[i]
    if not np.isfinite(joints).all():
        return update
    skeleton = _entity("skeleton", log_time)
    points = [joints[j] for bone in MODEL_BONES for j in bone]
    _line(skeleton, points, 0.03, OPPONENT, LinePrimitive.LINE_LIST)
    for joint in joints:
        _sphere(skeleton, joint, 0.06, OPPONENT)
    update.entities.append(skeleton)
    paddle = _entity("opponent_paddle", log_time)
    cylinder = paddle.cylinders.add(pose=_pose(scene.opponent_paddle[i], scene.opponent_paddle_rotation[i]),
                                    bottom_scale=1.0, top_scale=1.0, color=PADDLE_RED)
    _vector(cylinder.size, (2 * PADDLE_RADIUS, 2 * PADDLE_RADIUS, PADDLE_THICKNESS))  # normal: rotation's z
    update.entities.append(paddle)
    return update


def transforms(pose: dict, log_time: int) -> FrameTransforms:
    """table -> each arm frame, so that Foxglove can follow the paddle or any link."""
    message = FrameTransforms()
    for name, placement in pose["frames"].items():
        transform = FrameTransform(parent_frame_id=FRAME_ID, child_frame_id=name)
        transform.timestamp.FromNanoseconds(int(log_time))
        _vector(transform.translation, placement.translation)
        x, y, z, w = Rotation.from_matrix(placement.rotation).as_quat()
        transform.rotation.x, transform.rotation.y, transform.rotation.z, transform.rotation.w = x, y, z, w
        message.transforms.append(transform)
    return message


def scene_messages(scene: SceneEpisode, robot: Robot, visuals: pin.GeometryModel):
    """(topic, log_time, message) of every frame in time order; a SceneUpdate is its topic's whole state."""
    for i, log_time in enumerate(scene.log_times):
        log_time = int(log_time)
        pose = robot_pose(robot, visuals, scene.q[i])
        yield "/table", log_time, table_update(log_time)
        yield "/ball", log_time, ball_update(scene, i, log_time)
        yield "/prediction", log_time, prediction_update(scene, i, log_time)
        yield "/robot", log_time, robot_update(pose, log_time)
        yield "/opponent", log_time, opponent_update(scene, i, log_time)
        yield "/tf", log_time, transforms(pose, log_time)


def write_scene_mcap(path, scene: SceneEpisode, robot: Robot, visuals: pin.GeometryModel,
                     metadata: dict[str, dict[str, str]] | None = None) -> None:
    """The scene as an MCAP (protobuf foxglove.SceneUpdate and FrameTransforms, zstd chunks), written
    atomically; the episode's info goes into the metadata record 'episode', beside any given records."""
    with SceneWriter(path) as writer:
        for topic, log_time, message in scene_messages(scene, robot, visuals):
            writer.add(topic, log_time, message)
        writer.add_metadata("episode", {key: str(value) for key, value in scene.info.items()})
        for name, record in (metadata or {}).items():
            writer.add_metadata(name, record)
