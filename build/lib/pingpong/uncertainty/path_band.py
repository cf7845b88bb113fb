"""Conformal bands for the whole predicted post-hit path, reported beside the strike-point intervals.

A strike-point interval covers x at one y, the strike line. A band here is an interval at every y of the
grid Y_BAND whose coverage holds for the whole path at once: the true path x(y) inside at every grid y.

Simultaneous band: max-normalised-deviation split conformal, Mondrian by frame before the hit f.
1. Scale s_f(y) > 0: the mean |x_pred(y) - x_true(y)| over the training rows of frame f, floored at
   SCALE_FLOOR. The training rows must be the training hits' out-of-fold predictions (as for the learned
   parts in estimators.py): in-sample residuals shrink where the model fits its own hits and would misshape
   the band. The scale sees no calibration or test hit.
2. Score of a calibration row: max over grid y of |x_pred(y) - x_true(y)| / s_f(y).
3. q_f: the hit-grouped conformal quantile (conformal.py) at 1 - alpha of the frame-f calibration scores.
4. Band: x_pred(y) +- q_f s_f(y).
Why it covers: a row's score is <= q_f exactly when |x_pred(y) - x_true(y)| <= q_f s_f(y) at every grid y,
i.e. when the whole true path lies inside the band. s_f is fixed before calibration, so when hits are
exchangeable the frame-f scores of the calibration hits and of a test hit are too, and with one row per hit
and frame P(whole path inside) >= 1 - alpha for each frame (<= 1 - alpha + 1/(n_f + 1) with n_f
calibration hits and no ties). A hit's frames are dependent, so this holds per frame, not for all of a
hit's frames jointly. On Y_BAND it also holds between grid points: the join y = 0 is on the grid, so the
residual is linear between neighbours, its absolute value convex, and a band interpolated linearly
between grid points bounds it wherever it bounds it at both ends.

Pointwise band (the comparison): per frame and y, q_f(y) the conformal quantile of |x_pred(y) - x_true(y)|
alone. Each y is covered at 1 - alpha, but the whole path only when every y is at once, which is less often.
"""

from dataclasses import dataclass

import numpy as np
import pandas as pd

from pingpong.frames import STRIKE_Y
from pingpong.learning.loss import path_design
from pingpong.uncertainty.conformal import conformal_quantile, mondrian_quantiles

Y_BAND = np.round(np.arange(1.40, -1.40 - 1e-9, -0.05), 2)  # 57 values, m; holds the join 0 and STRIKE_Y
SCALE_FLOOR = 1e-3  # m: keeps every s_f(y) > 0; far below the cm-scale residuals, so it rarely binds
SIMULTANEOUS, POINTWISE = "simultaneous", "pointwise"


def path_x(params, y=Y_BAND) -> np.ndarray:
    """x (m) of the paths params (..., 3) = (a1, a2, b) at each y (m): (..., len(y))."""
    params = np.asarray(params, dtype=float)
    if params.shape[-1:] != (3,):
        raise ValueError(f"path_x: expected params (..., 3) = (a1, a2, b), got shape {params.shape}")
    return params @ path_design(y)


@dataclass(frozen=True, eq=False)  # eq=False: array fields have no single truth value
class PathBand:
    """A fitted band: half-width quantile[i] * scale[i] (m) at grid y for rows of frames[i].

    scale (frames, len(y)): s_f(y) in m (simultaneous) or 1 (pointwise). quantile: q_f (frames, 1),
    broadcast over y (simultaneous), or q_f(y) in m (frames, len(y)) (pointwise); +inf where too few hits.
    """

    kind: str
    alpha: float
    y: np.ndarray
    frames: tuple[int, ...]  # sorted
    scale: np.ndarray
    quantile: np.ndarray

    def __post_init__(self):
        shape = (len(self.frames), len(self.y))
        if np.shape(self.scale) != shape or np.shape(self.quantile) not in (shape, (shape[0], 1)):
            raise ValueError(f"PathBand: expected scale {shape} and quantile {shape} or ({shape[0]}, 1), got "
                             f"{np.shape(self.scale)} and {np.shape(self.quantile)}")

    def half_width(self, frames) -> np.ndarray:
        """(rows, len(y)) m for rows of these frames."""
        index = _frame_index(self.frames, frames)
        return self.quantile[index] * self.scale[index]

    def state(self) -> dict:
        """JSON-able (json writes an infinite quantile as Infinity and reads it back)."""
        return {"kind": self.kind, "alpha": self.alpha, "y": self.y.tolist(), "frames": list(self.frames),
                "scale": self.scale.tolist(), "quantile": self.quantile.tolist()}

    @classmethod
    def from_state(cls, state: dict) -> "PathBand":
        return cls(state["kind"], float(state["alpha"]), np.asarray(state["y"], dtype=float),
                   tuple(int(f) for f in state["frames"]), np.asarray(state["scale"], dtype=float),
                   np.asarray(state["quantile"], dtype=float))


def fit_path_band(train_pred, train_true, train_frames, cal_pred, cal_true, cal_frames, cal_groups,
                  alpha: float, y=Y_BAND) -> PathBand:
    """The simultaneous band (module doc): scales from the training rows (out-of-fold predictions),
    one quantile per frame from the calibration rows grouped by hit (cal_groups)."""
    y = _grid(y)
    train_error, train_frames, _ = _residuals("training", train_pred, train_true, train_frames, y)
    cal_error, cal_frames, cal_groups = _residuals("calibration", cal_pred, cal_true, cal_frames, y,
                                                   cal_groups)
    frames = _band_frames(cal_frames, train_frames)
    scale = np.stack([train_error[train_frames == f].mean(axis=0) for f in frames])
    scale = np.maximum(scale, SCALE_FLOOR)
    score = (cal_error / scale[_frame_index(frames, cal_frames)]).max(axis=1)
    by_frame = mondrian_quantiles(score, cal_frames, alpha, cal_groups)
    return PathBand(SIMULTANEOUS, alpha, y, frames, scale, np.array([[by_frame[f]] for f in frames]))


def fit_pointwise_band(cal_pred, cal_true, cal_frames, cal_groups, alpha: float, y=Y_BAND) -> PathBand:
    """The pointwise band: per frame and y, the hit-grouped conformal quantile of |x_pred(y) - x_true(y)|."""
    y = _grid(y)
    error, frames_of_row, groups = _residuals("calibration", cal_pred, cal_true, cal_frames, y, cal_groups)
    frames = _band_frames(frames_of_row)
    quantile = np.array([[conformal_quantile(error[frames_of_row == f, j], alpha, groups[frames_of_row == f])
                          for j in range(len(y))] for f in frames])
    return PathBand(POINTWISE, alpha, y, frames, np.ones_like(quantile), quantile)


def apply_band(band: PathBand, pred_params, frames) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) x (m), each (rows, len(band.y)), around the predicted paths."""
    pred = _params("apply_band pred_params", pred_params)
    half = band.half_width(_frames("apply_band frames", frames, len(pred)))
    x = path_x(pred, band.y)
    return x - half, x + half


def whole_path_covered(lower, upper, true_params, y=Y_BAND) -> np.ndarray:
    """(rows,) bool: the true path inside [lower, upper] at every y."""
    return _inside(lower, upper, true_params, y).all(axis=1)


def path_band_table(bands, pred_params, true_params, frames) -> pd.DataFrame:
    """One row per band (index: its kind) on these (test) rows: coverage of the whole path (overall and of
    the worst frame, with that frame), of the strike point, and mean half-widths (cm)."""
    pred = _params("path_band_table pred_params", pred_params)
    true = _params("path_band_table true_params", true_params, len(pred))
    frames = _frames("path_band_table frames", frames, len(pred))
    table = pd.DataFrame.from_records([_band_record(band, pred, true, frames) for band in bands])
    if not table["band"].is_unique:
        raise ValueError(f"path_band_table: expected one band per kind, got {table['band'].tolist()}")
    return table.set_index("band")


def _band_record(band: PathBand, pred, true, frames) -> dict:
    lower, upper = apply_band(band, pred, frames)
    inside = _inside(lower, upper, true, band.y)
    by_frame = pd.Series(inside.all(axis=1)).groupby(frames).mean()
    strike = _strike_index(band.y)
    half = (upper - lower) / 2
    return {"band": band.kind, "whole_path_coverage": inside.all(axis=1).mean(),
            "whole_path_coverage_min_frame": by_frame.min(), "worst_frame": int(by_frame.idxmin()),
            "strike_point_coverage": inside[:, strike].mean(), "mean_half_width_cm": 100 * half.mean(),
            "strike_half_width_cm": 100 * half[:, strike].mean()}


def _inside(lower, upper, true_params, y) -> np.ndarray:
    x = path_x(_params("true_params", true_params), _grid(y))
    if np.shape(lower) != x.shape or np.shape(upper) != x.shape:
        raise ValueError(f"expected lower and upper {x.shape} (rows, len(y)), got {np.shape(lower)} and "
                         f"{np.shape(upper)}")
    return (lower <= x) & (x <= upper)


def _strike_index(y: np.ndarray) -> int:
    at = np.flatnonzero(np.isclose(y, STRIKE_Y))
    if at.size != 1:
        raise ValueError(f"expected the strike line y = {STRIKE_Y} m once on the band's grid, "
                         f"found it {at.size} times")
    return int(at[0])


def _residuals(what, pred_params, true_params, frames, y, groups=None) -> tuple:
    """|x_pred(y) - x_true(y)| (rows, len(y)) m (x is linear in the parameters), frames, groups; checked."""
    pred = _params(f"{what} pred_params", pred_params)
    true = _params(f"{what} true_params", true_params, len(pred))
    if len(pred) == 0:
        raise ValueError(f"{what}: expected at least one row")
    frames = _frames(f"{what} frames", frames, len(pred))
    if groups is not None:
        groups = np.asarray(groups)
        if groups.shape != (len(pred),) or (groups.dtype.kind == "f" and not np.isfinite(groups).all()):
            raise ValueError(f"{what} groups: expected ({len(pred)},) finite hit labels, "
                             f"got shape {groups.shape}")
    return np.abs(path_x(pred - true, y)), frames, groups


def _params(name: str, params, rows: int | None = None) -> np.ndarray:
    params = np.asarray(params, dtype=float)
    if params.ndim != 2 or params.shape[1] != 3 or (rows is not None and len(params) != rows):
        raise ValueError(f"{name}: expected ({'rows' if rows is None else rows}, 3) path parameters "
                         f"(a1, a2, b), got shape {params.shape}")
    if not np.isfinite(params).all():
        raise ValueError(f"{name}: expected finite values, got {int((~np.isfinite(params)).sum())} "
                         "non-finite")
    return params


def _frames(name: str, frames, rows: int) -> np.ndarray:
    frames = np.asarray(frames)
    if frames.shape != (rows,):
        raise ValueError(f"{name}: expected ({rows},) frames before the hit, got shape {frames.shape}")
    if not (np.isfinite(frames).all() and (frames == np.round(frames)).all()):
        raise ValueError(f"{name}: expected finite whole frame counts")
    return frames.astype(int)


def _grid(y) -> np.ndarray:
    y = np.asarray(y, dtype=float)
    if y.ndim != 1 or y.size == 0 or not np.isfinite(y).all():
        raise ValueError(f"expected a non-empty finite 1-D grid of y (m), got shape {y.shape}")
    return y


def _band_frames(cal_frames: np.ndarray, train_frames: np.ndarray | None = None) -> tuple[int, ...]:
    """The calibration frames, sorted; with training frames, the two sets must match (scale and quantile)."""
    frames = tuple(np.unique(cal_frames).tolist())
    if train_frames is not None:
        trained = set(np.unique(train_frames).tolist())
        if no_cal := sorted(trained - set(frames)):
            raise ValueError(f"expected calibration rows for every training frame; frames {no_cal} "
                             "have none")
        if no_train := sorted(set(frames) - trained):
            raise ValueError(f"expected training rows for every calibration frame; frames {no_train} "
                             "have none")
    return frames


def _frame_index(band_frames: tuple[int, ...], frames) -> np.ndarray:
    """Each row's position in band_frames (sorted)."""
    frames = np.asarray(frames)
    missing = sorted(set(np.unique(frames).tolist()) - set(band_frames))
    if missing:
        raise ValueError(f"expected frames with calibration rows {list(band_frames)}; frames {missing} "
                         "have none")
    return np.searchsorted(band_frames, frames)
