"""What OpenPose reports for one camera frame, from the true 3D joints of everyone in view.

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


def _occluded(px: np.ndarray, depth: np.ndarray, others_px: list, others_depth: list, f: float) -> np.ndarray:
    """(25,) True where a nearer person's joints cover a joint's pixel (within their projected width)."""
    hidden = np.zeros(len(px), bool)
    for opx, odepth in zip(others_px, others_depth, strict=True):
        valid = odepth > 0.1
        if not valid.any():
            continue
        dist = np.linalg.norm(px[:, None, :] - opx[None, valid, :], axis=2)
        width = f * OCCLUDER_RADIUS / odepth[valid]
        nearer = odepth[valid][None, :] < depth[:, None]
        hidden |= ((dist < width[None, :]) & nearer).any(axis=1)
    return hidden


def simulate_openpose(camera: Camera, people_joints: list[np.ndarray], rng: np.random.Generator,
                      swap_rate: float = 0.01) -> np.ndarray:
    """OpenPose's people (P, 25, 3) [x px, y px, confidence] for one frame; absent joints are 0, 0, 0.

    people_joints: true BODY_25 joints (25, 3) per person (players and bystanders), table frame.
    """
    sigma = 3.0 * camera.width / 1440
    f = camera.K[0, 0]
    projected = [camera.project(j) for j in people_joints]
    depths = [camera.depth(j) for j in people_joints]
    out = []
    for i, (px, depth) in enumerate(zip(projected, depths, strict=True)):
        others = [k for k in range(len(people_joints)) if k != i]
        hidden = _occluded(px, depth, [projected[k] for k in others], [depths[k] for k in others], f)
        inside = (depth > 0.1) & (px[:, 0] >= 0) & (px[:, 0] < camera.width) & (px[:, 1] >= 0) \
            & (px[:, 1] < camera.height)
        scale = _JOINT_NOISE * np.where(hidden, 2.0, 1.0)
        noisy = px + rng.normal(0.0, 1.0, px.shape) * (sigma * scale)[:, None]
        confidence = np.where(hidden, rng.uniform(0.05, 0.4, 25), rng.uniform(0.55, 0.95, 25))
        detected = inside & ~(hidden & (rng.random(25) < 0.5)) & (rng.random(25) > 0.02)
        person = np.where(detected[:, None], np.column_stack([noisy, confidence]), 0.0)
        if detected.sum() < MIN_JOINTS:
            continue
        if rng.random() < swap_rate:
            right, left = LIMB_SWAPS[rng.integers(len(LIMB_SWAPS))]
            person[list(right + left)] = person[list(left + right)]
        out.append(person)
    order = rng.permutation(len(out))
    return np.array([out[k] for k in order]).reshape(-1, 25, 3)
