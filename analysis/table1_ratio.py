"""How much does Table 1's fall towards the hit depend on the hits drawn? A diagnostic.

The final model's median strike error 1 frame before the hit over its median 10 frames before (issue 18's
bar: <= 0.75; the paper's 0.63), with a 95 % percentile bootstrap interval over whole hits (scipy, 2000
resamples, paired: a hit keeps both its errors), on the test hits and, out of fold, on the training hits
(the cross-validation's one-seed models). Run from the repository root after the predict rule:
`.venv/bin/python analysis/table1_ratio.py`.
"""

import numpy as np
from scipy.stats import bootstrap

from pingpong.common.artifacts import read_table
from pingpong.curation.schemas import HIT_KEYS
from pingpong.learning.schemas import PREDICTIONS


def median_ratio(late, early, axis=-1):
    return np.median(late, axis=axis) / np.median(early, axis=axis)


def main() -> None:
    predictions = read_table("processed/predictions.parquet", PREDICTIONS)
    final = predictions[predictions["model"] == "final"]
    for split in ("test", "train"):
        errors = final[final["split"] == split].pivot_table(
            index=HIT_KEYS, columns="frames_before_hit", values="abs_error") * 100
        early, late = errors[10].to_numpy(), errors[1].to_numpy()
        interval = bootstrap((late, early), median_ratio, paired=True, vectorized=True, n_resamples=2000,
                             method="percentile", rng=np.random.default_rng(0)).confidence_interval
        print(f"{split}: {len(late)} hits, median error 10 / 1 frames before the hit "
              f"{np.median(early):.1f} / {np.median(late):.1f} cm, ratio {median_ratio(late, early):.2f} "
              f"(95 % {interval.low:.2f}-{interval.high:.2f})")


if __name__ == "__main__":
    main()
