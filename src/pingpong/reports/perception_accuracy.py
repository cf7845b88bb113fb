"""Perception against the twin's truth: one row per measured quantity, with the threshold it must meet.

Only twin runs have truth; the rows are what the perception tests assert and what
reports/tables/perception_accuracy.md shows.
"""

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation, Slerp

from pingpong.common.camera import Camera


def _row(quantity: str, value: float, unit: str, threshold: float, better: str = "below") -> dict:
    ok = value < threshold if better == "below" else value >= threshold
    return {"quantity": quantity, "value": value, "unit": unit, "threshold": threshold,
            "must_be": better, "ok": bool(ok)}


def calibration_rows(calibrated: list[Camera], reports: list[dict], truth: list[Camera]) -> list[dict]:
    """Reprojection RMS and camera-centre error per camera (centres compared by name)."""
    true_by_name = {c.name: c for c in truth}
    rows = []
    for cam, rep in zip(calibrated, reports, strict=True):
        rms = max(rep["intrinsics_rms_px"], rep["extrinsics_rms_px"])
        rows.append(_row(f"{cam.name} reprojection RMS", rms, "px", 0.5))
        err = np.linalg.norm(cam.center - true_by_name[cam.name].center)
        rows.append(_row(f"{cam.name} centre error", 100 * err, "cm", 1.0))
    return rows


def paddle_rows(measured: pd.DataFrame, truth: pd.DataFrame) -> list[dict]:
    """Median position (mm) and rotation (deg) error of the valid resampled paddle poses."""
    rows = []
    for player, m in measured[measured["valid"]].groupby("player"):
        t = truth[truth["player"] == player]
        tt, mt = t["time_ns"].to_numpy(), m["time_ns"].to_numpy()
        true_pos = np.column_stack([np.interp(mt, tt, t[c].to_numpy()) for c in ("px", "py", "pz")])
        pos_err = np.linalg.norm(m[["px", "py", "pz"]].to_numpy() - true_pos, axis=1)
        rot_cols = [f"r{i}{j}" for i in range(3) for j in range(3)]
        true_rot = Slerp(tt, Rotation.from_matrix(t[rot_cols].to_numpy().reshape(-1, 3, 3)))(mt)
        ang = (true_rot.inv() * Rotation.from_matrix(m[rot_cols].to_numpy().reshape(-1, 3, 3))).magnitude()
        rows.append(_row(f"paddle {player} position error (median)", 1e3 * np.median(pos_err), "mm", 2.0))
        rows.append(_row(f"paddle {player} rotation error (median)", np.degrees(np.median(ang)), "deg", 1.0))
    return rows
