"""The paper's time-to-hit uncertainty: the error's linear trend over the frames before the hit."""

import numpy as np


def fit_trend(frames_before_hit, abs_errors) -> tuple[float, float]:
    """(intercept m, slope m per frame) of the least-squares line |error| ~ frames before the hit."""
    slope, intercept = np.polyfit(np.asarray(frames_before_hit, float), np.asarray(abs_errors, float), 1)
    return float(intercept), float(slope)


def trend(intercept: float, slope: float, frames_before_hit) -> np.ndarray:
    """The expected absolute error (m) at each frame; kept >= 0."""
    return np.maximum(intercept + slope * np.asarray(frames_before_hit, float), 0.0)
