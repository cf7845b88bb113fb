"""What OpenPose reports for a camera's frames, from the true 3D joints of everyone in view: a keypoint
detector's errors, at rates set in config twin.keypoint_errors (`KeypointErrors`).

Per person and frame (`simulate_openpose_frames`):
- Noise that scales with the person's size in the image: per joint, an RMS 2D error of
  sigma_scale * sigma_i * s, where sigma_i is COCO's per-keypoint standard deviation of the error as a
  share of the object scale s = sqrt(area) (COCO keypoint evaluation, cocodataset.org/#keypoints-eval;
  the values of pycocotools' cocoeval.py, `COCO_SIGMAS`), and s is taken from the joints' bounding box
  (`object_scale`). The error is correlated over frames (an AR(1) process of correlation_s), as a
  detector's is: it errs the same way on similar images.
- Occlusion: joints behind the own trunk from the camera's view (`self_hidden`) or behind a nearer
  person (`_occluded`) err hidden_scale times more, get confidences 0.05-0.4 (below the pose stage's
  0.3 mostly), and are lost (written 0, 0, 0, as OpenPose writes a missing joint) with probability
  hidden_miss.
- Motion: a joint moving in the image during the exposure (exposure_s) lands anywhere on its streak,
  and its confidence falls with the streak's length against the joint's noise.
- Left/right swaps of a whole arm, leg or foot, starting at swap_rate per person and frame and lasting
  swap_frames on average; the swapped joints' confidences drop (x 0.5-0.9).
- Visible joints lost at miss_rate; joints outside the image or behind the camera are 0; people with
  fewer than MIN_JOINTS joints are not reported, and the order of the people is shuffled.
False people (spectators walking behind the far court, `spectator_joints`) are added by the rule.
"""

from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy.signal import lfilter

from pingpong.common.camera import Camera
from pingpong.common.config import Settings
from pingpong.frames import BODY25, FRAME_NS, TABLE_HALF_LENGTH
from pingpong.twin.players import FLOOR_Z, base_frame, body_dims, pose_joints, sample_player_style

J = {name: i for i, name in enumerate(BODY25)}
# BODY_25 index groups that OpenPose confuses as a whole when it swaps sides
LIMB_SWAPS = (((2, 3, 4), (5, 6, 7)), ((9, 10, 11), (12, 13, 14)), ((22, 23, 24), (19, 20, 21)))
# COCO's per-keypoint sigmas (pycocotools cocoeval.py: [.26 .25 .25 .35 .35 .79 .79 .72 .72 .62 .62 1.07
# 1.07 .87 .87 .89 .89] / 10 for nose, eyes, ears, shoulders, elbows, wrists, hips, knees, ankles),
# mapped onto BODY_25; the neck and mid-hip (not COCO keypoints) as the shoulders and hips, the feet
# (toes, heels) as the ankles.
_COCO = {"Nose": 0.026, "Eye": 0.025, "Ear": 0.035, "Shoulder": 0.079, "Elbow": 0.072, "Wrist": 0.062,
         "Hip": 0.107, "Knee": 0.087, "Ankle": 0.089, "Neck": 0.079, "BigToe": 0.089, "SmallToe": 0.089,
         "Heel": 0.089}
COCO_SIGMAS = np.array([_COCO[n[1:] if n[0] in "RL" and n[1:] in _COCO else n.removeprefix("Mid")]
                        for n in BODY25])
# A person's segment area as a share of the bounding box of its keypoints: COCO's scale is the segment
# area's root, and detectors evaluated without masks take 0.53 of the box (luxonis-train's and
# Ultralytics' OKS area_factor).
AREA_PER_BOX = 0.53
OCCLUDER_RADIUS = 0.15  # m, a person's width around the line of their joints, for occlusion tests
TRUNK_HALF_WIDTH = 0.17  # m, the trunk's half width about the neck to mid-hip line (chest, ~0.1 h)
TRUNK_HALF_DEPTH = 0.10  # m, a joint this far behind the trunk's axis is behind the trunk
TRUNK_AXIS = (J["Neck"], J["MidHip"])
MIN_JOINTS = 6


@dataclass(frozen=True)
class KeypointErrors(Settings):
    """config twin.keypoint_errors (defaults and meanings in config/schema.yaml)."""

    sigma_scale: float
    correlation_s: float
    hidden_scale: float
    hidden_miss: float
    miss_rate: float
    swap_rate: float
    swap_frames: float
    exposure_s: float
    false_people_rate: float


def default_keypoint_errors(**changes) -> KeypointErrors:
    """config/schema.yaml's defaults (a test holds them equal), with changes, for tests and benchmarks."""
    values = dict(sigma_scale=0.82, correlation_s=0.1, hidden_scale=2.0, hidden_miss=0.5, miss_rate=0.02,
                  swap_rate=0.045, swap_frames=3.0, exposure_s=0.004, false_people_rate=0.3)
    return KeypointErrors(**{**values, **changes})


@dataclass
class Carry:
    """What one chunk of frames leaves to the next: each person's last unit noise (P, 25, 2), and the
    swap under way (frames left (P,), limb (P,))."""

    noise: np.ndarray | None = None
    swap_left: np.ndarray | None = None
    swap_limb: np.ndarray | None = None
    _ready: bool = field(default=False, repr=False)

    def start(self, n_people: int, rng: np.random.Generator) -> None:
        if not self._ready:
            self.noise = rng.normal(0.0, 1.0, (n_people, 25, 2))
            self.swap_left = np.zeros(n_people, int)
            self.swap_limb = np.zeros(n_people, int)
            self._ready = True


def _occluded(px: np.ndarray, depth: np.ndarray, f: float) -> np.ndarray:
    """(P, n, 25) True where a nearer person's joints cover a joint's pixel (within their projected width).

    px (P, n, 25, 2), depth (P, n, 25): every person's projected joints per frame (NaN: absent). Each pair
    of people is tested joint against joint only in the frames where they can overlap (`_bounds`):
    elsewhere no joint can cover another."""
    hidden = np.zeros(depth.shape, bool)
    x, y = px[..., 0], px[..., 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        width2 = (f * OCCLUDER_RADIUS / depth) ** 2  # (P, n, 25) squared occluder half-width, px^2
        box, cover_box, nearest, farthest = _bounds(px, depth, width2)
        for i in range(len(px)):
            for k in range(len(px)):
                if k == i:
                    continue
                overlap = (box[i, :, 1] > cover_box[k, :, 0]) & (box[i, :, 0] < cover_box[k, :, 1])
                frames = np.flatnonzero(overlap.all(axis=-1) & (nearest[k] < farthest[i]))
                xi, yi, xk, yk = x[i, frames], y[i, frames], x[k, frames], y[k, frames]
                # x and y apart: a sum over a last axis of 2 cost as much as the rest of the test
                dx, dy = xi[:, :, None] - xk[:, None], yi[:, :, None] - yk[:, None]
                dist2 = dx * dx + dy * dy  # (frames, 25 of i, 25 of k)
                dk, di = depth[k, frames], depth[i, frames]
                covers = (dist2 < width2[k, frames][:, None]) & (dk[:, None] < di[:, :, None]) \
                    & (dk[:, None] > 0.1)
                hidden[i, frames] |= covers.any(axis=2)
    return hidden


def _bounds(px: np.ndarray, depth: np.ndarray, width2: np.ndarray) -> tuple[np.ndarray, ...]:
    """Per person and frame, what decides whether two people can overlap: the box of the joints (P, n, 2
    low/high, 2 x/y), px; the box of the joints that can cover another (depth > 0.1 m) grown by the widest
    of their half-widths; the nearest such joint's depth and the farthest joint's depth (P, n), m. A joint
    of i that k covers lies in k's grown box, behind k's nearest joint. The growth is widened by a relative
    1e-9 so that rounding never drops a frame the joint test would keep; NaN (absent) never overlaps."""
    can_cover = depth > 0.1
    reach = np.sqrt(np.fmax.reduce(np.where(can_cover, width2, np.nan), axis=-1)) * (1 + 1e-9) + 1e-9
    covering = np.where(can_cover[..., None], px, np.nan)
    box = np.stack(joint_extent(px), axis=-2)
    cover_low, cover_high = joint_extent(covering)
    cover_box = np.stack([cover_low - reach[..., None], cover_high + reach[..., None]], axis=-2)
    nearest = np.fmin.reduce(np.where(can_cover, depth, np.nan), axis=-1)
    return box, cover_box, nearest, np.fmax.reduce(depth, axis=-1)


def self_hidden(px: np.ndarray, depth: np.ndarray, f: float) -> np.ndarray:
    """(..., 25) True where a joint lies behind the person's own trunk from the camera: its pixel within
    the trunk's projected half width of the neck to mid-hip segment, and deeper than the trunk's axis
    there by more than TRUNK_HALF_DEPTH (a hand in front of the chest seen from behind, the far shoulder
    seen from the side). px (..., 25, 2), depth (..., 25). x and y apart (sums over a last axis of 2 cost
    more than the arithmetic; the same values)."""
    x, y = px[..., 0], px[..., 1]
    ax, ay = x[..., TRUNK_AXIS[0], None], y[..., TRUNK_AXIS[0], None]
    abx, aby = x[..., TRUNK_AXIS[1], None] - ax, y[..., TRUNK_AXIS[1], None] - ay
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.clip(((x - ax) * abx + (y - ay) * aby) / (abx * abx + aby * aby), 0.0, 1.0)
        dx, dy = x - (ax + t * abx), y - (ay + t * aby)
        dist = np.sqrt(dx * dx + dy * dy)
        axis_depth = depth[..., TRUNK_AXIS[0], None] * (1 - t) + depth[..., TRUNK_AXIS[1], None] * t
        hidden = (dist < f * TRUNK_HALF_WIDTH / axis_depth) & (depth > axis_depth + TRUNK_HALF_DEPTH)
    hidden[..., list(TRUNK_AXIS)] = False
    return hidden


def joint_extent(px: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) (..., 2) of joints (..., 25, 2) over the joints, NaN ignored (all NaN: NaN). The joints
    axis made the last and contiguous first: a reduction along it runs 5x faster than across it."""
    by_axis = np.ascontiguousarray(np.moveaxis(px, -1, -2))  # (..., 2, 25)
    return np.fmin.reduce(by_axis, axis=-1), np.fmax.reduce(by_axis, axis=-1)


def object_scale(px: np.ndarray) -> np.ndarray:
    """(...,) COCO's object scale s = sqrt(area) of people's projected joints (..., 25, 2), px: the root of
    AREA_PER_BOX of their bounding box; NaN where a person is absent."""
    with np.errstate(invalid="ignore"):
        low, high = joint_extent(px)
        extent = high - low
        return np.sqrt(AREA_PER_BOX * extent[..., 0] * extent[..., 1])


def project_pixels(camera: Camera, points: np.ndarray) -> np.ndarray:
    """camera.project's pixels (N, 2) of world points (N, 3), bit for bit, without its cost: OpenCV's
    Python projectPoints always computes the (2N, 15) Jacobian too, 3-5x the projection's own time (0.8 s
    of a camera's 1.6 M joints). The same operations in the same order as OpenCV's cvProjectPoints2 for the
    5-coefficient model (R from Rodrigues of Rodrigues(R), as projectPoints gets it; the higher
    coefficients are zero, so their terms leave every value unchanged); tests hold it equal to OpenCV."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    R = cv2.Rodrigues(cv2.Rodrigues(camera.R)[0])[0]
    t = camera.t.astype(np.float64)
    k1, k2, p1, p2, k3 = np.asarray(camera.dist, np.float64)
    X, Y, Z = pts[:, 0], pts[:, 1], pts[:, 2]
    x = R[0, 0] * X + R[0, 1] * Y + R[0, 2] * Z + t[0]
    y = R[1, 0] * X + R[1, 1] * Y + R[1, 2] * Z + t[1]
    z = R[2, 0] * X + R[2, 1] * Y + R[2, 2] * Z + t[2]
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(z != 0, 1.0 / z, 1.0)
    x, y = x * z, y * z
    r2 = x * x + y * y
    r4 = r2 * r2
    r6 = r4 * r2
    a1, a2, a3 = 2 * x * y, r2 + 2 * x * x, r2 + 2 * y * y
    cdist = 1 + k1 * r2 + k2 * r4 + k3 * r6
    xd = x * cdist + p1 * a1 + p2 * a2
    yd = y * cdist + p1 * a3 + p2 * a1
    K = camera.K
    return np.column_stack([xd * K[0, 0] + K[0, 2], yd * K[1, 1] + K[1, 2]])


def projected_people(camera: Camera, joints: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(present (P, n), pixels (P, n, 25, 2), camera depths (P, n, 25)) of true joints (P, n, 25, 3); a
    person whose joints are all NaN in a frame is absent there, and their pixels and depths are NaN."""
    n_people, n = joints.shape[:2]
    present = ~np.isnan(joints).all(axis=-1).all(axis=-1)
    flat = np.where(present[..., None, None], joints, 0.0).reshape(-1, 3)
    depth = camera.depth(flat).reshape(n_people, n, 25)
    px = np.full((n_people, n, 25, 2), np.nan)  # absent people are not projected (a bystander is, a fifth)
    px[present] = project_pixels(camera, joints[present].reshape(-1, 3)).reshape(-1, 25, 2)
    depth[~present] = np.nan
    return present, px, depth


def _correlated_noise(shape: tuple, carry: Carry, errors: KeypointErrors, rng) -> np.ndarray:
    """Unit-variance Gaussian noise (P, n, 25, 2), AR(1) along the frames with correlation time
    errors.correlation_s, continuing carry.noise (updated)."""
    a = np.exp(-FRAME_NS * 1e-9 / errors.correlation_s) if errors.correlation_s > 0 else 0.0
    innovation = rng.normal(0.0, 1.0, shape) * np.sqrt(1 - a * a)
    noise, _ = lfilter([1.0], [1.0, -a], innovation, axis=1, zi=a * carry.noise[:, None])
    carry.noise = noise[:, -1]
    return noise


def _blur(px: np.ndarray, errors: KeypointErrors, rng) -> tuple[np.ndarray, np.ndarray]:
    """(offsets (P, n, 25, 2), streak lengths (P, n, 25) px): where on its motion streak during the
    exposure each joint is found (uniform along it), from its image velocity."""
    if px.shape[1] < 2:
        return np.zeros(px.shape), np.zeros(px.shape[:-1])
    # px/s; 0 where a neighbouring frame lacks the person
    velocity = np.nan_to_num(np.gradient(px, axis=1)) / (FRAME_NS * 1e-9)
    streak = velocity * errors.exposure_s
    along = rng.uniform(-0.5, 0.5, px.shape[:-1])
    return streak * along[..., None], np.linalg.norm(streak, axis=-1)


def _swaps(kept: np.ndarray, carry: Carry, errors: KeypointErrors, rng) -> np.ndarray:
    """(P, n) the limb (index into LIMB_SWAPS) swapped in each detection, -1 where none: swaps start at
    swap_rate per detection and last a geometric number of frames of mean swap_frames."""
    out = np.full(kept.shape, -1)
    starts = rng.random(kept.shape) < errors.swap_rate
    lengths = rng.geometric(1.0 / max(errors.swap_frames, 1.0), kept.shape)
    limbs = rng.integers(len(LIMB_SWAPS), size=kept.shape)
    for i in range(kept.shape[0]):
        left, limb = carry.swap_left[i], carry.swap_limb[i]
        for frame in range(kept.shape[1]):
            if left <= 0 and starts[i, frame] and kept[i, frame]:
                left, limb = lengths[i, frame], limbs[i, frame]
            if left > 0:
                out[i, frame] = limb if kept[i, frame] else -1
                left -= 1
        carry.swap_left[i], carry.swap_limb[i] = left, limb
    return out


def simulate_openpose_frames(camera: Camera, people_joints: np.ndarray, rng: np.random.Generator,
                             errors: KeypointErrors, carry: Carry | None = None) -> list[np.ndarray]:
    """OpenPose's people (p, 25, 3) [x px, y px, confidence] for each of n frames; absent joints are 0, 0, 0.

    people_joints: true BODY_25 joints (P, n, 25, 3) per person (players, bystanders, spectators) and
    frame, table frame; a person whose joints are all NaN in a frame is not there. carry: the state a
    previous chunk of the same people's frames left (a new one when None). Vectorised over frames.
    """
    joints = np.asarray(people_joints, float)
    carry = carry or Carry()
    carry.start(len(joints), rng)
    present, px, depth = projected_people(camera, joints)
    f = camera.K[0, 0]
    hidden = _occluded(px, depth, f) | self_hidden(px, depth, f)
    with np.errstate(invalid="ignore"):
        inside = (depth > 0.1) & (px[..., 0] >= 0) & (px[..., 0] < camera.width) & (px[..., 1] >= 0) \
            & (px[..., 1] < camera.height)
    sigma = errors.sigma_scale * COCO_SIGMAS * object_scale(px)[..., None]  # (P, n, 25) RMS 2D error, px
    per_axis = sigma / np.sqrt(2) * np.where(hidden, errors.hidden_scale, 1.0)
    offsets, streak = _blur(px, errors, rng)
    noisy = px + _correlated_noise(px.shape, carry, errors, rng) * per_axis[..., None] + offsets
    with np.errstate(invalid="ignore", divide="ignore"):
        sharp = np.exp(-np.nan_to_num(streak / sigma))  # 1 when still, falls as the streak outgrows the noise
    confidence = np.where(hidden, rng.uniform(0.05, 0.4, hidden.shape),
                          rng.uniform(0.55, 0.95, hidden.shape) * (0.5 + 0.5 * sharp))
    lost = rng.random(hidden.shape) < np.where(hidden, errors.hidden_miss, errors.miss_rate)
    detected = inside & ~lost
    people = np.where(detected[..., None], np.concatenate([noisy, confidence[..., None]], axis=-1), 0.0)
    kept = present & (detected.sum(axis=-1) >= MIN_JOINTS)
    swapped = _swaps(kept, carry, errors, rng)
    for limb, (right, left) in enumerate(LIMB_SWAPS):
        i, frame = np.nonzero(swapped == limb)
        sides = list(right + left)
        people[i[:, None], frame[:, None], sides] = people[i[:, None], frame[:, None], list(left + right)]
        people[i[:, None], frame[:, None], sides, 2] *= rng.uniform(0.5, 0.9, (len(i), len(sides)))
    order = np.argsort(np.where(kept, rng.random(kept.shape), np.inf), axis=0)  # a random order per frame
    return [people[order[:count, frame], frame] for frame, count in enumerate(kept.sum(axis=0))]


def simulate_openpose(camera: Camera, people_joints: list[np.ndarray], rng: np.random.Generator,
                      errors: KeypointErrors) -> np.ndarray:
    """OpenPose's people (P, 25, 3) for one frame of true BODY_25 joints (25, 3) per person
    (`simulate_openpose_frames` of that one frame: no motion blur, fresh noise)."""
    if not people_joints:
        return np.zeros((0, 25, 3))
    return simulate_openpose_frames(camera, np.stack(people_joints)[:, None], rng, errors)[0]


SPECTATOR_SPEED = (0.9, 1.4)  # m/s, walking
SPECTATOR_BEHIND = (1.5, 2.5)  # m behind a table end's players' area (|y| up to 4.37 m): beyond the court


def spectator_mask(n_frames: int, rate: float, rng: np.random.Generator) -> np.ndarray:
    """(n,) frames in which a spectator is in the hall: intervals of 3-15 s covering about `rate` of them."""
    present = np.zeros(n_frames, bool)
    frames_per_s = 1e9 / FRAME_NS
    while rate > 0 and present.mean() < rate:
        length = int(rng.uniform(3.0, 15.0) * frames_per_s)
        start = rng.integers(0, max(n_frames - length, 1))
        present[start:start + length] = True
    return present


def spectator_joints(n_frames: int, rate: float, rng: np.random.Generator) -> np.ndarray:
    """BODY_25 joints (n, 25, 3) of a spectator (NaN where absent) walking to and fro behind one table
    end, beyond the players' areas, in about `rate` of the frames: a false person for the pose stages
    (seen by the cameras of the other end). Arms swing, feet slide with the body (no gait)."""
    t = np.arange(n_frames) * FRAME_NS * 1e-9
    style = sample_player_style(rng)
    dims = body_dims(style)
    side = rng.choice([-1.0, 1.0])
    y = side * (TABLE_HALF_LENGTH + 3.0 + rng.uniform(*SPECTATOR_BEHIND))
    speed, span = rng.uniform(*SPECTATOR_SPEED), rng.uniform(2.0, 3.5)
    phase = (speed * t / (2 * span) + rng.random()) % 1.0  # to and fro over x in [-span, span]
    x = span * (4 * np.abs(phase - 0.5) - 1)
    heading = np.where(np.gradient(x) >= 0, 1.0, -1.0)
    root = np.column_stack([x, np.full(n_frames, y), np.full(n_frames, FLOOR_Z + 0.98 * dims.hip_height)])
    out = np.empty((n_frames, 25, 3))
    swing = 0.25 * np.sin(2 * np.pi * 0.9 * t)  # arm swing, m
    for sign in (-1.0, 1.0):
        walking = heading == sign
        if not walking.any():
            continue
        base = base_frame(np.array([sign, 0.0]))
        neck = root[walking] + [0.0, 0.0, dims.torso]
        wrists = np.stack([neck + base @ (np.array([s * 0.17, 0.0, -0.5]) * style.height / 1.75)
                           for s in (1.0, -1.0)], 1)
        wrists[:, 0] += base[:, 1] * swing[walking, None]
        wrists[:, 1] -= base[:, 1] * swing[walking, None]
        hints = np.stack([neck + base @ np.array([s * 0.4, -0.3, -0.3]) for s in (1.0, -1.0)], 1)
        n = int(walking.sum())
        out[walking] = pose_joints(dims, base, root[walking], np.zeros(n), np.full(n, 0.05), wrists, hints,
                                   root[walking], 0.25, 0.0)
    out[~spectator_mask(n_frames, rate, rng)] = np.nan
    return out
