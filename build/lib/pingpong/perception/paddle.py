"""Paddle poses: OptiTrack rigid bodies resampled onto the camera clock and moved into the table frame.

OptiTrack reports poses in its own world frame at its own rate (>= 120 Hz) with dropouts when
markers are occluded. Positions are interpolated linearly, rotations by slerp; a target time
that falls in a dropout longer than `max_gap_s` or outside the recording is marked invalid
(NaN), never filled in.
"""

import warnings

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation, Slerp

from pingpong.common.rigid import apply_transform, rotate_matrices
from pingpong.frames import ROT_COLUMNS

# the coarsest clock the readers take: Motive CSV exports give times to the microsecond, so a dropout of
# exactly max_gap_s reads as 50.000 ms there and as 50.000004 ms in a stream whose 240 Hz ticks are
# rounded to the nanosecond; within this of the limit a gap counts as at the limit
GAP_TOLERANCE_NS = 1_000


def resample_poses(
    time_ns: np.ndarray,
    positions: np.ndarray,
    quats_xyzw: np.ndarray,
    target_time_ns: np.ndarray,
    max_gap_s: float = 0.05,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poses at target_time_ns (T,) from samples at time_ns (M,): positions (T, 3), rotations (T, 3, 3)
    and valid (T,). Invalid targets (in a gap longer than max_gap_s, or outside the samples) are NaN.

    Unsorted or duplicated sample times are sorted and deduplicated (first sample kept) with a
    warning; samples with NaN (or a zero quaternion) count as dropouts.
    """
    time_ns = np.asarray(time_ns, np.int64)
    positions = np.asarray(positions, float)
    quats = np.asarray(quats_xyzw, float)
    targets = np.asarray(target_time_ns, np.int64)
    if positions.shape != (len(time_ns), 3) or quats.shape != (len(time_ns), 4):
        raise ValueError(f"need positions (M, 3) and quaternions (M, 4) for M={len(time_ns)} times, "
                         f"got {positions.shape} and {quats.shape}")
    if np.any(np.diff(time_ns) < 0):
        warnings.warn("pose timestamps are not sorted; sorting them", stacklevel=2)
    order = np.argsort(time_ns, kind="stable")
    time_ns, positions, quats = time_ns[order], positions[order], quats[order]
    first = np.r_[True, np.diff(time_ns) > 0]
    if not first.all():
        warnings.warn(f"{np.count_nonzero(~first)} duplicated pose timestamps; "
                      "keeping the first sample of each", stacklevel=2)
    good = first & np.isfinite(positions).all(axis=1) & np.isfinite(quats).all(axis=1)
    good &= np.linalg.norm(np.where(np.isfinite(quats), quats, 0.0), axis=1) > 0
    time_ns, positions, quats = time_ns[good], positions[good], quats[good]

    out_positions = np.full((len(targets), 3), np.nan)
    out_rotations = np.full((len(targets), 3, 3), np.nan)
    valid = np.zeros(len(targets), bool)
    if len(time_ns) < 2:
        return out_positions, out_rotations, valid
    i = np.clip(np.searchsorted(time_ns, targets, side="right") - 1, 0, len(time_ns) - 2)
    t0, t1 = time_ns[i], time_ns[i + 1]
    on_sample = (targets == t0) | (targets == t1)
    valid = (targets >= time_ns[0]) & (targets <= time_ns[-1])
    valid &= (t1 - t0 <= round(max_gap_s * 1e9) + GAP_TOLERANCE_NS) | on_sample
    i, t0, t1 = i[valid], t0[valid], t1[valid]
    weight = ((targets[valid] - t0) / (t1 - t0))[:, None]
    out_positions[valid] = (1 - weight) * positions[i] + weight * positions[i + 1]
    # times relative to the first sample, so that float64 holds the nanoseconds exactly
    slerp = Slerp((time_ns - time_ns[0]).astype(float), Rotation.from_quat(quats))
    out_rotations[valid] = slerp((targets[valid] - time_ns[0]).astype(float)).as_matrix()
    return out_positions, out_rotations, valid


def to_table_frame(
    positions: np.ndarray, rotations: np.ndarray, T_table_from_optitrack: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Positions (T, 3) and rotations (T, 3, 3) from OptiTrack's world frame into the table frame."""
    return (apply_transform(T_table_from_optitrack, positions),
            rotate_matrices(T_table_from_optitrack, rotations))












def paddle_table(optitrack: dict[str, pd.DataFrame], bodies: dict[str, str],
                 T_table_from_optitrack: np.ndarray, frame_times_ns: np.ndarray,
                 max_gap_s: float = 0.05) -> pd.DataFrame:
    """Each player's paddle in the table frame on the camera clock; gaps are rows with valid = False."""
    parts = []
    for player, body in bodies.items():
        if body not in optitrack:
            raise ValueError(f"rigid body '{body}' (player '{player}') not in the OptiTrack stream; "
                             f"bodies there: {sorted(optitrack)}")
        df = optitrack[body]
        pos, rot, valid = resample_poses(df["time_ns"].to_numpy(), df[["x", "y", "z"]].to_numpy(),
                                         df[["qx", "qy", "qz", "qw"]].to_numpy(), frame_times_ns, max_gap_s)
        pos, rot = to_table_frame(pos, rot, T_table_from_optitrack)
        parts.append(pd.DataFrame({"time_ns": frame_times_ns, "player": player,
                                   **{f"p{a}": pos[:, k] for k, a in enumerate("xyz")},
                                   **dict(zip(ROT_COLUMNS, rot.reshape(-1, 9).T, strict=True)),
                                   "valid": valid}))
    return pd.concat(parts, ignore_index=True)
