"""The simulated robot: KUKA LBR iiwa 14 R820 on a Ridgeback base, loaded with Pinocchio (table frame, SI).

Configuration q (9,): base_x, base_y (m, prismatic, in the table plane), then the arm joints 1-7 (rad);
the velocity vector has the same layout. The paddle frame's origin is the disc centre and its z axis
the disc normal; "facing the opponent" means that normal points along +y.
"""

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pinocchio as pin
import yaml

PADDLE_RADIUS = 0.08  # m
N_BASE = 2  # the first two joints are the base's


@dataclass(frozen=True, eq=False)
class Robot:
    model: pin.Model
    data: pin.Data  # Pinocchio's scratch space, overwritten by every call
    paddle_frame: int
    flange_frame: int
    joint_names: tuple[str, ...]
    q_min: np.ndarray  # (9,) m / rad
    q_max: np.ndarray
    v_max: np.ndarray  # (9,) m/s / rad/s
    a_max: np.ndarray  # (9,) m/s^2 / rad/s^2
    tau_max: np.ndarray  # (7,) Nm, arm joints only (the base's forces are not modelled)
    q_home: np.ndarray  # (9,) ready posture
    urdf_path: str  # the URDF it was built from (the scene's visual shapes are read from it)


ACCELERATION_SETS = ("table6", "drake")  # limits.yaml's acceleration sets (its header cites both)


def read_limits(path: Path, accelerations: str = "table6") -> dict:
    """limits.yaml as arrays: names, q_min, q_max, v_max, a_max (9,) of the named acceleration set,
    tau_max (7,), home (9,)."""
    if accelerations not in ACCELERATION_SETS:
        raise ValueError(f"acceleration set '{accelerations}': expected one of {ACCELERATION_SETS}")
    doc = yaml.safe_load(Path(path).read_text())
    joints = doc["joints"]
    for j in joints:
        if not isinstance(j.get("acceleration"), dict) or accelerations not in j["acceleration"]:
            raise ValueError(f"{path}: joint {j.get('name')} has no '{accelerations}' acceleration; expected "
                             f"acceleration: {{{', '.join(f'{a}: ...' for a in ACCELERATION_SETS)}}}")
    position = np.array([j["position"] for j in joints], float)
    return {
        "names": tuple(j["name"] for j in joints),
        "q_min": position[:, 0], "q_max": position[:, 1],
        "v_max": np.array([j["velocity"] for j in joints], float),
        "a_max": np.array([j["acceleration"][accelerations] for j in joints], float),
        "tau_max": np.array([j["torque"] for j in joints if "torque" in j], float),
        "home": np.array(doc["home"], float),
    }


def load_robot(urdf_path: Path, limits_path: Path, accelerations: str = "table6") -> Robot:
    """Build the Pinocchio model from the URDF and attach the limits of limits.yaml (joint order checked),
    with its named acceleration set (ACCELERATION_SETS).

    The files come in through the rule's `input:` (config/robot/), so Snakemake reruns on their edits."""
    model = pin.buildModelFromUrdf(str(urdf_path))
    limits = read_limits(limits_path, accelerations)
    names = tuple(model.names[1:])
    if names != limits["names"]:
        raise ValueError(f"{limits_path}: joints {limits['names']} do not match the URDF's {names}")
    return Robot(model, model.createData(), model.getFrameId("paddle"), model.getFrameId("flange"), names,
                 limits["q_min"], limits["q_max"], limits["v_max"], limits["a_max"], limits["tau_max"],
                 limits["home"], str(urdf_path))


def with_dynamics(robot: Robot, base_acceleration: float, base_speed: float) -> Robot:
    """The robot with its base joints' acceleration (m/s^2) and speed (m/s) replaced (a regime's dynamics;
    the arm's come from the limits file's acceleration set)."""
    a_max, v_max = robot.a_max.copy(), robot.v_max.copy()
    a_max[:N_BASE], v_max[:N_BASE] = base_acceleration, base_speed
    return replace(robot, a_max=a_max, v_max=v_max)


def regime_robot(urdf_path: Path, limits_path: Path, dynamics) -> Robot:
    """load_robot with a regime's dynamics (regimes.Dynamics): its arm acceleration set, base limits and
    where the base waits (the home posture's base x moved by base_start_x_m)."""
    robot = load_robot(urdf_path, limits_path, dynamics.arm_accelerations)
    robot = with_dynamics(robot, dynamics.base_acceleration_mps2, dynamics.base_speed_mps)
    if dynamics.base_start_x_m == 0:
        return robot
    home = robot.q_home.copy()
    x = robot.joint_names.index("base_x")
    home[x] += dynamics.base_start_x_m
    if not robot.q_min[x] <= home[x] <= robot.q_max[x]:
        raise ValueError(f"base start x {home[x]} m lies outside the base's square [{robot.q_min[x]}, "
                         f"{robot.q_max[x]}] m")
    return replace(robot, q_home=home)


def frame_pose(robot: Robot, q: np.ndarray, frame: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Position (3,) and rotation (3, 3) of a frame (default: the paddle) in the table frame."""
    frame = robot.paddle_frame if frame is None else frame
    pin.forwardKinematics(robot.model, robot.data, q)
    placement = pin.updateFramePlacement(robot.model, robot.data, frame)
    return placement.translation.copy(), placement.rotation.copy()


def paddle_position(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Paddle centre (3,) in the table frame."""
    return frame_pose(robot, q)[0]


def paddle_jacobian(robot: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Paddle position (3,), rotation (3, 3) and 6D Jacobian (6, 9) in LOCAL_WORLD_ALIGNED.

    Rows 0-2 map q_dot to the paddle centre's velocity in the table frame, rows 3-5 to its angular
    velocity. computeFrameJacobian runs the forward kinematics itself, so one call gives all three.
    """
    jac = pin.computeFrameJacobian(robot.model, robot.data, q, robot.paddle_frame,
                                   pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
    placement = pin.updateFramePlacement(robot.model, robot.data, robot.paddle_frame)
    return placement.translation, placement.rotation, jac


def random_configurations(robot: Robot, rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, 9) configurations uniform within the position limits."""
    return rng.uniform(robot.q_min, robot.q_max, size=(n, len(robot.q_min)))


def worst_case_accelerations(robot: Robot, rng: np.random.Generator, n_samples: int = 2000,
                             with_velocity: bool = True) -> dict[str, np.ndarray]:
    """Acceleration (rad/s^2) each arm joint can reach at every sampled state, from the torque limits.

    Joint i alone accelerates (the others held: q_ddot = a e_i) under the bias torque b = C(q, v) v + g(q)
    (pin.rnea with zero acceleration) at configurations uniform in the limits and, with_velocity,
    velocities uniform in the limits. Every joint j must then supply tau_j = M_ji a + b_j within
    +-tau_max_j whatever the sign of a, so the reachable |a| at that state is
        simple:  (tau_max_i - |b_i|) / M_ii                      (joint i's own torque only)
        coupled: min_j (tau_max_j - |b_j|) / |M_ji|              (also holding the other joints still)
    Each is reduced by a minimum over the samples (the worst case), with the median beside it. States
    where some |b_j| > tau_max_j (the arm cannot even hold itself) count as 0. The base joints are not
    included (their drive forces are unpublished; limits.yaml takes the paper's 15 m/s^2), and the reaction
    of base accelerations on the arm is neglected.
    """
    model, data = robot.model, robot.data
    arm = slice(N_BASE, model.nv)
    tau_max = robot.tau_max
    simple, coupled = [], []
    for q in random_configurations(robot, rng, n_samples):
        v = rng.uniform(-robot.v_max, robot.v_max) if with_velocity else np.zeros(model.nv)
        bias = np.abs(pin.rnea(model, data, q, v, np.zeros(model.nv))[arm])
        mass = pin.crba(model, data, q)[arm, arm]
        mass = np.triu(mass) + np.triu(mass, 1).T  # crba fills the upper triangle only
        margin = np.maximum(tau_max - bias, 0.0)
        simple.append(margin / np.diag(mass))
        with np.errstate(divide="ignore"):
            coupled.append(np.min(margin[:, None] / np.abs(mass), axis=0))
    simple, coupled = np.array(simple), np.array(coupled)
    return {"simple_min": simple.min(axis=0), "simple_median": np.median(simple, axis=0),
            "coupled_min": coupled.min(axis=0), "coupled_median": np.median(coupled, axis=0)}
