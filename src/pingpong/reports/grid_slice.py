"""The search's winner beside named nets (config training.grid_extra: the paper's own net, the default
net) on the test hits: each the mean of its cross-validation fold models, Table 1's median strike error at
10 / 1 / 0 frames before the hit, and each net's difference to the winner with a paired bootstrap interval
over whole hits."""

import numpy as np
import pandas as pd

from pingpong.curation.schemas import HIT_KEYS
from pingpong.reports.summary import TABLE1_FRAMES, bootstrap_interval


def _median_difference(a, b, axis=-1):
    return np.median(a, axis=axis) - np.median(b, axis=axis)


def hit_errors(predictions: pd.DataFrame) -> pd.DataFrame:
    """(hits, frames before the hit) absolute strike error (cm) of one net's test predictions
    (learning.cv.prediction_table's rows)."""
    return predictions.pivot_table(index=HIT_KEYS, columns="frames_before_hit", values="abs_error") * 100


def grid_slice_table(errors: dict[str, pd.DataFrame], ids: dict[str, str], val_loss: dict[str, float],
                     seed: int, n_resamples: int = 2000) -> pd.DataFrame:
    """One row per net (errors' keys, the winner first) and frame of TABLE1_FRAMES: the median strike error
    (cm) with its 95 % interval, and the net's median minus the winner's with a paired interval."""
    rng = np.random.default_rng(seed)
    names = list(errors)
    winner = errors[names[0]]
    rows = []
    for name in names:
        e = errors[name].reindex(winner.index)
        for frame in TABLE1_FRAMES:
            mine, best = e[frame].to_numpy(), winner[frame].to_numpy()
            low, high = bootstrap_interval((mine,), np.median, n_resamples, rng)
            d_low, d_high = ((0.0, 0.0) if name == names[0]
                             else bootstrap_interval((mine, best), _median_difference, n_resamples, rng))
            rows.append({"net": name, "config_id": ids[name], "mean_val_loss": val_loss[name],
                         "frames_before_hit": frame, "median_cm": float(np.median(mine)), "low_cm": low,
                         "high_cm": high, "minus_winner_cm": float(np.median(mine) - np.median(best)),
                         "minus_winner_low_cm": d_low, "minus_winner_high_cm": d_high, "n_hits": len(mine)})
    return pd.DataFrame(rows)
