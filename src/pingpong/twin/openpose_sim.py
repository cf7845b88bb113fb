"""What OpenPose reports for a camera's frames, from the true 3D joints of everyone in view.

Per person: project the BODY_25 joints (with distortion), add pixel noise (std 3 px at 1440 px
width, scaled with the image width, 1.5x at wrists and ankles), give confidences (0.55-0.95 when
clear, 0.05-0.4 when occluded by a nearer person, those dropped with probability 0.5), zero joints
outside the image or behind the camera, drop people with fewer than 6 joints left, swap one
left/right limb now and then, and shuffle the order of the people.
"""

import numpy as np

from pingpong.common.camera import Camera

# BODY_25 index groups that OpenPose confuses as a whole when it swaps sides
LIMB_SWAPS = (((2, 3, 4), (5, 6, 7)), ((9, 10, 11), (12, 13, 14)), ((22, 23, 24), (19, 20, 21)))
NOISY_JOINTS = (4, 7, 11, 14)  # wrists and ankles
_JOINT_NOISE = np.where(np.isin(np.arange(25), NOISY_JOINTS), 1.5, 1.0)  # per joint, relative
OCCLUDER_RADIUS = 0.15  # m, a person's width around the line of their joints, for occlusion tests
MIN_JOINTS = 6


def _occluded(px: np.ndarray, depth: np.ndarray, f: float) -> np.ndarray:
    """(P, n, 25) True where a nearer person's joints cover a joint's pixel (within their projected width).

    px (P, n, 25, 2), depth (P, n, 25): every person's projected joints per frame (NaN: absent)."""
    hidden = np.zeros(depth.shape, bool)
    x, y = px[..., 0], px[..., 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        width2 = (f * OCCLUDER_RADIUS / depth) ** 2  # (P, n, 25) squared occluder half-width, px^2
        for i in range(len(px)):
            for k in range(len(px)):
                if k == i:
                    continue
                # x and y apart: a sum over a last axis of 2 cost as much as the rest of the test
                dx, dy = x[i][:, :, None] - x[k][:, None], y[i][:, :, None] - y[k][:, None]
                dist2 = dx * dx + dy * dy  # (n, 25 of i, 25 of k)
                covers = (dist2 < width2[k][:, None]) & (depth[k][:, None] < depth[i][:, :, None]) \
                    & (depth[k][:, None] > 0.1)
                hidden[i] |= covers.any(axis=2)
    return hidden


def projected_people(camera: Camera, joints: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(present (P, n), pixels (P, n, 25, 2), camera depths (P, n, 25)) of true joints (P, n, 25, 3); a
    person whose joints are all NaN in a frame is absent there, and their pixels and depths are NaN."""
    n_people, n = joints.shape[:2]
    present = ~np.isnan(joints).all(axis=-1).all(axis=-1)
    flat = np.where(present[..., None, None], joints, 0.0).reshape(-1, 3)
    px = camera.project(flat).reshape(n_people, n, 25, 2)
    depth = camera.depth(flat).reshape(n_people, n, 25)
    px[~present], depth[~present] = np.nan, np.nan
    return present, px, depth


def simulate_openpose_frames(camera: Camera, people_joints: np.ndarray, rng: np.random.Generator,
                             swap_rate: float = 0.01) -> list[np.ndarray]:
    """OpenPose's people (p, 25, 3) [x px, y px, confidence] for each of n frames; absent joints are 0, 0, 0.

    people_joints: true BODY_25 joints (P, n, 25, 3) per person (players and bystanders) and frame, table
    frame; a person whose joints are all NaN in a frame is not there. Vectorised over frames (per frame
    the work is a few dozen tiny array operations).
    """
    joints = np.asarray(people_joints, float)
    present, px, depth = projected_people(camera, joints)
    hidden = _occluded(px, depth, camera.K[0, 0])
    with np.errstate(invalid="ignore"):
        inside = (depth > 0.1) & (px[..., 0] >= 0) & (px[..., 0] < camera.width) & (px[..., 1] >= 0) \
            & (px[..., 1] < camera.height)
    sigma = 3.0 * camera.width / 1440
    scale = _JOINT_NOISE * np.where(hidden, 2.0, 1.0)
    noisy = px + rng.normal(0.0, 1.0, px.shape) * (sigma * scale)[..., None]
    confidence = np.where(hidden, rng.uniform(0.05, 0.4, hidden.shape), rng.uniform(0.55, 0.95, hidden.shape))
    detected = inside & ~(hidden & (rng.random(hidden.shape) < 0.5)) & (rng.random(hidden.shape) > 0.02)
    people = np.where(detected[..., None], np.concatenate([noisy, confidence[..., None]], axis=-1), 0.0)
    kept = present & (detected.sum(axis=-1) >= MIN_JOINTS)
    for i, frame in zip(*np.nonzero(kept & (rng.random(kept.shape) < swap_rate)), strict=True):
        right, left = LIMB_SWAPS[rng.integers(len(LIMB_SWAPS))]
        people[i, frame, list(right + left)] = people[i, frame, list(left + right)]
    order = np.argsort(np.where(kept, rng.random(kept.shape), np.inf), axis=0)  # a random order per frame
    return [people[order[:count, frame], frame] for frame, count in enumerate(kept.sum(axis=0))]


def simulate_openpose(camera: Camera, people_joints: list[np.ndarray], rng: np.random.Generator,
                      swap_rate: float = 0.01) -> np.ndarray:
    """OpenPose's people (P, 25, 3) for one frame of true BODY_25 joints (25, 3) per person
    (`simulate_openpose_frames` of that one frame)."""
    if not people_joints:
        return np.zeros((0, 25, 3))
    return simulate_openpose_frames(camera, np.stack(people_joints)[:, None], rng, swap_rate)[0]
