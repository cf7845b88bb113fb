"""Human bodies of the lab twin: player styles, body proportions, the BODY_25 skeleton, bystanders.

The skeleton is built by forward kinematics of a rigid pelvis, trunk and head plus two-link inverse
kinematics for the arms and legs, so every bone keeps its length exactly whatever the motion (the
strokes themselves are planned in `strokes.py`). A body's base frame is a rotation whose columns are
the body's right, forward and up directions in the table frame.
"""

from dataclasses import dataclass

import numpy as np

from pingpong.frames import BODY25, TABLE_HALF_LENGTH, TABLE_HALF_WIDTH

FLOOR_Z = -0.76  # table surface is z = 0
J = {name: i for i, name in enumerate(BODY25)}
# Pairs of BODY_25 keypoints a rigid bone joins (every pair keeps its distance over any motion).
BONES = (
    ("Neck", "MidHip"), ("Neck", "RShoulder"), ("Neck", "LShoulder"), ("RShoulder", "LShoulder"),
    ("RShoulder", "RElbow"), ("RElbow", "RWrist"), ("LShoulder", "LElbow"), ("LElbow", "LWrist"),
    ("MidHip", "RHip"), ("MidHip", "LHip"), ("RHip", "RKnee"), ("RKnee", "RAnkle"),
    ("LHip", "LKnee"), ("LKnee", "LAnkle"), ("Neck", "Nose"), ("Nose", "REye"), ("Nose", "LEye"),
    ("REye", "REar"), ("LEye", "LEar"), ("RAnkle", "RHeel"), ("RAnkle", "RBigToe"),
    ("RAnkle", "RSmallToe"), ("LAnkle", "LHeel"), ("LAnkle", "LBigToe"), ("LAnkle", "LSmallToe"),
)


@dataclass(frozen=True)
class PlayerStyle:
    """What makes one player move differently from another; drawn by `sample_player_style`."""

    height: float  # m
    arm_scale: float  # arm lengths relative to the average proportions of this height
    leg_scale: float
    handedness: int  # +1 right-handed, -1 left-handed
    stance_width: float  # m between the ankles
    distance_behind: float  # m, MidHip behind the end line in the ready position
    home_offset: float  # m, ready position shifted from the table's centre line to the backhand side
    tracking_gain: float  # fraction of the ball's lateral offset followed before the stroke starts
    forehand_threshold: float  # m; ball further than this to the playing side of the body: forehand
    crouch: float  # MidHip height relative to standing straight
    lean: float  # rad, forward trunk lean in the ready position
    prep_time: float  # s, the stroke (side-step, backswing) starts this long before the hit
    swing_time: float  # s, from the top of the backswing to the hit
    follow_time: float  # s, from the hit to the end of the follow-through
    recovery_time: float  # s, from the hit back to the ready position
    intent_lead: float  # s before the hit at which the pose starts to depend on the target
    intent_gain: float  # how strongly the trunk shows the target (1 = average player)
    late_window: float  # s, a late change of intent turns the wrist over this last interval
    noise: float  # m, per-stroke jitter of the keyframes (rotations: noise / 0.25 m rad)
    paddle_reach: float  # m, wrist joint to paddle centre


def sample_player_style(rng: np.random.Generator) -> PlayerStyle:
    """A random adult player, mostly right-handed."""
    return PlayerStyle(
        height=float(np.clip(rng.normal(1.75, 0.08), 1.55, 1.98)),
        arm_scale=float(np.clip(rng.normal(1.0, 0.03), 0.92, 1.08)),
        leg_scale=float(np.clip(rng.normal(1.0, 0.03), 0.92, 1.08)),
        handedness=1 if rng.random() < 0.88 else -1,
        stance_width=float(rng.uniform(0.45, 0.70)),
        distance_behind=float(rng.uniform(0.3, 1.0)),
        home_offset=float(rng.uniform(0.0, 0.2)),
        tracking_gain=float(rng.uniform(0.4, 0.7)),
        forehand_threshold=float(rng.uniform(-0.15, 0.05)),
        crouch=float(rng.uniform(0.86, 0.93)),
        lean=float(rng.uniform(0.2, 0.4)),
        prep_time=float(rng.uniform(0.50, 0.65)),
        swing_time=float(rng.uniform(0.14, 0.22)),
        follow_time=float(rng.uniform(0.15, 0.22)),
        recovery_time=float(rng.uniform(0.45, 0.60)),
        intent_lead=float(rng.uniform(0.20, 0.40)),
        intent_gain=float(rng.uniform(0.7, 1.3)),
        late_window=float(rng.uniform(0.10, 0.15)),
        noise=float(rng.uniform(0.01, 0.03)),
        paddle_reach=float(rng.uniform(0.15, 0.19)),
    )


@dataclass(frozen=True)
class BodyDims:
    """Segment lengths (m) and rigid keypoint offsets (body axes right, forward, up; m)."""

    torso: float  # MidHip to Neck
    shoulder_half: float
    hip_half: float
    upper_arm: float
    forearm: float
    thigh: float
    shank: float
    ankle_height: float
    head: np.ndarray  # (5, 3) Nose, REye, LEye, REar, LEar relative to the Neck, head frame
    foot: np.ndarray  # (3, 3) BigToe, SmallToe, Heel relative to a right ankle (x mirrored for left)
    paddle_reach: float

    @property
    def arm_reach(self) -> float:
        return self.upper_arm + self.forearm

    @property
    def hip_height(self) -> float:
        return self.thigh + self.shank + self.ankle_height


def body_dims(style: PlayerStyle) -> BodyDims:
    """Segment lengths from the height by the usual anthropometric proportions (Winter's tables)."""
    h = style.height
    return BodyDims(
        torso=0.288 * h,
        shoulder_half=0.129 * h,
        hip_half=0.055 * h,
        upper_arm=0.186 * h * style.arm_scale,
        forearm=0.146 * h * style.arm_scale,
        thigh=0.245 * h * style.leg_scale,
        shank=0.246 * h * style.leg_scale,
        ankle_height=0.039 * h,
        head=h * np.array([[0.0, 0.055, 0.105], [0.018, 0.045, 0.125], [-0.018, 0.045, 0.125],
                           [0.043, -0.005, 0.115], [-0.043, -0.005, 0.115]]),
        foot=h * np.array([[-0.012, 0.085, -0.039], [0.022, 0.075, -0.039], [0.0, -0.030, -0.039]]),
        paddle_reach=style.paddle_reach,
    )


def rot_z(angle: np.ndarray) -> np.ndarray:
    """Rotations about z, (..., 3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    z, o = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def rot_x(angle: np.ndarray) -> np.ndarray:
    """Rotations about x, (..., 3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    z, o = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2)


def base_frame(forward_xy: np.ndarray) -> np.ndarray:
    """Base rotation (columns right, forward, up) of a body facing the horizontal direction forward_xy."""
    f = np.array([forward_xy[0], forward_xy[1], 0.0])
    f /= np.linalg.norm(f)
    return np.column_stack([np.cross(f, [0.0, 0.0, 1.0]), f, [0.0, 0.0, 1.0]])


def player_base(side: int) -> np.ndarray:
    """Base frame of a player standing at the side*y end of the table, facing the table."""
    return base_frame(np.array([0.0, -float(side)]))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def two_link(root: np.ndarray, target: np.ndarray, l1: float, l2: float, hint: np.ndarray):
    """Middle and end joints (T, 3) of a chain root -l1- middle -l2- end reaching for target (T, 3).

    The end lands on the target when it is in reach, else at the nearest reachable point on the line
    to it; the middle joint (elbow, knee) lies on its circle of solutions as close as possible to hint.
    """
    d_vec = target - root
    d = np.linalg.norm(d_vec, axis=-1)
    u = d_vec / np.maximum(d, 1e-9)[:, None]
    d_ok = np.clip(d, abs(l1 - l2) + 1e-3, (l1 + l2) * (1 - 1e-4))
    end = np.where((d_ok == d)[:, None], target, root + u * d_ok[:, None])
    a = (l1**2 - l2**2 + d_ok**2) / (2 * d_ok)
    rho = np.sqrt(np.maximum(l1**2 - a**2, 0.0))
    p = hint - root
    p_perp = p - np.sum(p * u, -1, keepdims=True) * u
    # Hint on the chain's axis: any perpendicular does (never happens with the hints used here).
    fallback = np.cross(u, [0.0, 0.0, 1.0]) + 1e-3 * np.cross(u, [1.0, 0.0, 0.0])
    p_perp = np.where(np.linalg.norm(p_perp, axis=-1, keepdims=True) > 1e-6, p_perp, fallback)
    mid = root + a[:, None] * u + rho[:, None] * _unit(p_perp)
    return mid, end


def pose_joints(dims: BodyDims, base: np.ndarray, root: np.ndarray, twist: np.ndarray, lean: np.ndarray,
                wrists: np.ndarray, elbow_hints: np.ndarray, feet_anchor: np.ndarray,
                stance_width: float, stagger: float) -> np.ndarray:
    """BODY_25 joints (T, 25, 3) of a body from its driving signals.

    root: MidHip (T, 3); twist: trunk rotation about the vertical (T,), rad, positive to the left
    (the pelvis turns half as far); lean: forward trunk lean (T,); wrists, elbow_hints: (T, 2, 3)
    wished wrist positions and elbow hints of the right and left arm (a wrist out of reach stops at
    the arm's length); feet_anchor: (T, 3) point the feet stand around (x, y used); stagger: m the right
    foot stands behind the left. The trunk, pelvis and head are rigid, arms and legs two-link chains.
    """
    n = len(root)
    trunk = base @ rot_z(twist) @ rot_x(-lean)
    pelvis = base @ rot_z(0.5 * twist)
    head = base @ rot_z(0.4 * twist) @ rot_x(-0.5 * lean - 0.1)
    out = np.empty((n, 25, 3))
    out[:, J["MidHip"]] = root
    neck = root + trunk[:, :, 2] * dims.torso
    out[:, J["Neck"]] = neck
    for name, sign in (("R", 1.0), ("L", -1.0)):
        k = 0 if name == "R" else 1
        shoulder = neck + sign * dims.shoulder_half * trunk[:, :, 0]
        elbow, wrist = two_link(shoulder, wrists[:, k], dims.upper_arm, dims.forearm, elbow_hints[:, k])
        out[:, J[name + "Shoulder"]], out[:, J[name + "Elbow"]], out[:, J[name + "Wrist"]] = (
            shoulder, elbow, wrist)
        hip = root + sign * dims.hip_half * pelvis[:, :, 0]
        ankle_target = feet_anchor + base @ np.array([sign * stance_width / 2, -stagger * (sign > 0), 0.0])
        ankle_target[:, 2] = FLOOR_Z + dims.ankle_height
        knee_hint = hip + 0.5 * pelvis[:, :, 1] + 0.1 * sign * pelvis[:, :, 0]
        knee, ankle = two_link(hip, ankle_target, dims.thigh, dims.shank, knee_hint)
        out[:, J[name + "Hip"]], out[:, J[name + "Knee"]], out[:, J[name + "Ankle"]] = hip, knee, ankle
        toe_out = base @ rot_z(np.array(-sign * 0.25))  # feet point slightly outwards
        foot = dims.foot * np.array([sign, 1.0, 1.0])
        for part, off in zip(("BigToe", "SmallToe", "Heel"), foot, strict=True):
            out[:, J[name + part]] = ankle + toe_out @ off
    for name, off in zip(("Nose", "REye", "LEye", "REar", "LEar"), dims.head, strict=True):
        out[:, J[name]] = neck + head @ off
    return out


HAND_BEYOND_WRIST = 0.4  # the hand's centre lies beyond the wrist by this share of the forearm (twin.render)


def free_hand_to(joints: np.ndarray, dims: BodyDims, handedness: int, target: np.ndarray,
                 weight: np.ndarray) -> np.ndarray:
    """BODY_25 joints (T, 25, 3) with the free arm re-solved where weight (T,) > 0: its hand's centre
    moved from where it is towards target (T, 3) by weight (1: at the target, or the nearest point the arm
    reaches). The arm is a two-link chain whose end is the hand's centre, 1 + HAND_BEYOND_WRIST forearms
    from the elbow, so both bones keep their lengths; the elbow stays as near its place as it can.
    Other joints and frames are returned unchanged (the same array where weight is all 0)."""
    moved = np.flatnonzero(weight > 0)
    if len(moved) == 0:
        return joints
    free = "L" if handedness > 0 else "R"
    shoulder, elbow, wrist = (J[free + name] for name in ("Shoulder", "Elbow", "Wrist"))
    out = joints.copy()
    arm = joints[moved]
    hand = arm[:, wrist] + HAND_BEYOND_WRIST * (arm[:, wrist] - arm[:, elbow])
    goal = hand + weight[moved, None] * (target[moved] - hand)
    reach = (1 + HAND_BEYOND_WRIST) * dims.forearm
    new_elbow, end = two_link(arm[:, shoulder], goal, dims.upper_arm, reach, arm[:, elbow])
    out[moved, elbow] = new_elbow
    out[moved, wrist] = new_elbow + (end - new_elbow) / (1 + HAND_BEYOND_WRIST)
    return out


def bystander_joints(times: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """BODY_25 joints (T, 25, 3) of an onlooker standing beside the table, swaying and shifting a little.

    For sessions where the pose estimator also sees people other than the two players.
    """
    t = np.asarray(times, dtype=float)
    style = sample_player_style(rng)
    dims = body_dims(style)
    side_x = rng.choice([-1.0, 1.0])
    spot = np.array([side_x * (TABLE_HALF_WIDTH + rng.uniform(0.8, 2.0)),
                     rng.uniform(-TABLE_HALF_LENGTH, TABLE_HALF_LENGTH), 0.0])
    yaw = rng.normal(0.0, 0.4)
    base = base_frame(np.array([-side_x * np.cos(yaw), np.sin(yaw)]))
    freq, phase = rng.uniform(0.1, 0.5, 4), rng.uniform(0, 2 * np.pi, 4)
    wave = np.sin(2 * np.pi * freq[None] * t[:, None] + phase[None])  # (T, 4) slow independent sways
    root = spot + np.outer(0.05 * wave[:, 0], base[:, 0]) + np.outer(0.04 * wave[:, 1], base[:, 1])
    root[:, 2] = FLOOR_Z + 0.99 * dims.hip_height + 0.005 * wave[:, 2]
    twist, lean = 0.15 * wave[:, 3], np.full(len(t), 0.05)
    trunk = base @ rot_z(twist)
    neck = root + trunk[:, :, 2] * dims.torso
    # Arms hanging (or held in front when the draw says so), elbows pointing out and back.
    front = rng.uniform(0.0, 0.25)
    wrists = np.stack([neck + trunk @ (np.array([s * 0.17, front, -0.45]) * style.height / 1.75)
                       for s in (1.0, -1.0)], 1)
    hints = np.stack([neck + trunk @ np.array([s * 0.4, -0.3, -0.3]) for s in (1.0, -1.0)], 1)
    return pose_joints(dims, base, root, twist, lean, wrists, hints, root, 0.3, 0.0)
