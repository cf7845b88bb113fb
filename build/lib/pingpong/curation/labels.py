"""Mirroring hits onto one direction, the paper's two-line labels, and strike points.

Mirroring convention: a rotation by pi about the table's z axis, (x, y, z) -> (-x, -y, z), applied to
every hit whose ball travels towards +y, so that all kept hits travel towards -y. A rotation, not the
reflection y -> -y: it keeps the frame right-handed, so a right-handed player stays right-handed (their
RShoulder is still their right shoulder, no joint relabelling), paddle orientations stay proper
rotations (det +1), spin (a pseudovector) and the Magnus force keep their physics, and gravity and the
table (symmetric under it) are unchanged. A reflection would turn right-handers into left-handers and
flip sidespin. Under the rotation the labels map as (a1, a2, b) -> (a2, a1, -b) (mirror_labels).

That reflection, x -> -x, is still a hit physics allows: the same stroke by a player of the other hand,
with mirrored spin (mechanics is mirror symmetric). `reflect_frames` and `reflect_labels` make it, for
training-set augmentation only (pingpong.learning.train); curation never uses them.
"""

import numpy as np

from pingpong.frames import MODEL_JOINTS, N_INPUT, STRIKE_Y

MIRROR = np.diag([-1.0, -1.0, 1.0])  # rotation by pi about z
N_POINTS = len(MODEL_JOINTS) + 1  # the joints and the paddle position lead the 39-value frame
PADDLE_POSITION = slice(3 * (N_POINTS - 1), 3 * N_POINTS)
PADDLE_ROTATION = slice(3 * N_POINTS, 3 * N_POINTS + 9)
BALL = slice(N_INPUT - 3, N_INPUT)
# x -> -x swaps the body's sides: each model joint's index after the reflection
REFLECTED_JOINTS = tuple(MODEL_JOINTS.index({"R": "L", "L": "R"}[j[0]] + j[1:]) for j in MODEL_JOINTS)
REFLECT = np.diag([-1.0, 1.0, 1.0])  # table frame
REFLECT_PADDLE_BODY = np.diag([1.0, -1.0, 1.0])  # keeps handle-to-tip and the face normal (columns 0, 2)


def mirror_points(points) -> np.ndarray:
    """Points or vectors (..., 3) rotated by pi about z: (x, y, z) -> (-x, -y, z)."""
    return np.asarray(points, float) * np.diag(MIRROR)


def mirror_rotations(rotations) -> np.ndarray:
    """Orientations (..., 3, 3) (body-to-table rotation matrices) after the mirror: MIRROR @ R."""
    return MIRROR @ np.asarray(rotations, float)


def mirror_frames(frames) -> np.ndarray:
    """Model input frames (..., 39) mirrored: 8 joints and the paddle position as points, the paddle
    rotation (row-major) as an orientation (its first two rows change sign), the ball as a point."""
    frames = np.asarray(frames, float)
    if frames.shape[-1] != N_INPUT:
        raise ValueError(f"expected frames of {N_INPUT} values, got shape {frames.shape}")
    out = frames.copy()
    lead = frames.shape[:-1]
    out[..., :3 * N_POINTS] = mirror_points(frames[..., :3 * N_POINTS].reshape(*lead, N_POINTS, 3)).reshape(
        *lead, 3 * N_POINTS)
    rotation = frames[..., PADDLE_ROTATION].reshape(*lead, 3, 3)
    out[..., PADDLE_ROTATION] = mirror_rotations(rotation).reshape(*lead, 9)
    out[..., BALL] = mirror_points(frames[..., BALL])
    return out


def reflect_frames(frames) -> np.ndarray:
    """Model input frames (..., 39) of the left-right reflected hit (x -> -x): right and left joints
    swap, points negate x, the paddle keeps a proper rotation (REFLECT @ R @ REFLECT_PADDLE_BODY).
    Frames of the ball alone (..., 3), the ball-only baseline's, negate x."""
    frames = np.asarray(frames, float)
    if frames.shape[-1] == 3:
        return frames @ REFLECT
    if frames.shape[-1] != N_INPUT:
        raise ValueError(f"expected frames of {N_INPUT} values (or the ball's 3), got shape {frames.shape}")
    lead = frames.shape[:-1]
    points = frames[..., :3 * N_POINTS].reshape(*lead, N_POINTS, 3)
    order = [*REFLECTED_JOINTS, N_POINTS - 1]  # joints swapped, the paddle position last as before
    out = frames.copy()
    out[..., :3 * N_POINTS] = (points[..., order, :] @ REFLECT).reshape(*lead, 3 * N_POINTS)
    rotation = frames[..., PADDLE_ROTATION].reshape(*lead, 3, 3)
    out[..., PADDLE_ROTATION] = (REFLECT @ rotation @ REFLECT_PADDLE_BODY).reshape(*lead, 9)
    out[..., BALL] = frames[..., BALL] @ REFLECT
    return out


def reflect_labels(labels) -> np.ndarray:
    """Labels (..., 3) = (a1, a2, b) of the reflected path: x -> -x negates all three."""
    return -np.asarray(labels, float)


def mirror_labels(a1, a2, b):
    """Labels of the mirrored path: x'(y') = -x(-y') swaps the two slopes and negates the intercept."""
    return a2, a1, -b


def fit_two_lines(y, x) -> tuple[float, float, float]:
    """Labels (a1, a2, b): least squares of x = a1 y + b (y >= 0), a2 y + b (y < 0), joined at y = 0.

    Linear least squares on the design matrix [y (y >= 0), y (y < 0), 1]; non-finite pairs are left out.
    A slope with no sample of nonzero y on its side is undetermined and comes back NaN (b is then the
    other line's intercept).
    """
    y, x = np.asarray(y, float).ravel(), np.asarray(x, float).ravel()
    keep = np.isfinite(y) & np.isfinite(x)
    y, x = y[keep], x[keep]
    design = np.column_stack([y * (y >= 0), y * (y < 0), np.ones_like(y)])
    has_side = np.abs(design[:, :2]).max(axis=0, initial=0.0) > 0
    if len(y) < 1 + has_side.sum():
        raise ValueError(f"{len(y)} finite samples cannot fix {1 + has_side.sum()} line parameters")
    columns = np.flatnonzero(np.concatenate([has_side, [True]]))
    solution, *_ = np.linalg.lstsq(design[:, columns], x, rcond=None)
    labels = np.full(3, np.nan)
    labels[columns] = solution
    return float(labels[0]), float(labels[1]), float(labels[2])


def x_of_y(a1, a2, b, y) -> np.ndarray:
    """x on the two-line path at y (all arguments broadcast)."""
    y = np.asarray(y, float)
    return np.where(y >= 0, np.asarray(a1) * y, np.asarray(a2) * y) + np.asarray(b)


def strike_point_from_labels(a1, a2, b, strike_y: float = STRIKE_Y) -> np.ndarray:
    """Strike x (m) the labels give on the strike line (vectorised)."""
    return x_of_y(a1, a2, b, strike_y)


def measured_strike_point(ball_post_hit, strike_y: float = STRIKE_Y) -> tuple[float, float]:
    """(x, z) of the ball where its post-hit flight (T, 3) first crosses y = strike_y going towards -y,
    interpolated linearly between the samples either side (NaN rows skipped); (NaN, NaN) if it does not."""
    p = np.asarray(ball_post_hit, float)
    p = p[np.isfinite(p).all(axis=1)]
    d = p[:, 1] - strike_y
    crossing = np.flatnonzero((d[:-1] > 0) & (d[1:] <= 0))
    if len(crossing) == 0:
        return np.nan, np.nan
    k = crossing[0]
    f = d[k] / (d[k] - d[k + 1])
    x, _, z = p[k] + f * (p[k + 1] - p[k])
    return float(x), float(z)


def labels_of_path(ball_post_hit, strike_y: float = STRIKE_Y) -> tuple[float, float, float]:
    """Labels fitted to a mirrored post-hit flight (T, 3): its (x, y) from the hit up to and including
    the first sample past the strike line (later samples, a ball falling off the table's end, are no
    part of the path the robot has to meet)."""
    p = np.asarray(ball_post_hit, float)
    past = np.flatnonzero(p[:, 1] <= strike_y)
    end = past[0] + 1 if len(past) else len(p)
    return fit_two_lines(p[:end, 1], p[:end, 0])
