"""Table 1 of each seed of the final model against their mean: how much of the error is one seed's luck?

The final model is the selected configuration refit on the training part with seeds seed + 0 .. seeds - 1
(processed/models/final/seed*.safetensors), predicting as their mean (a deep ensemble's point prediction,
Lakshminarayanan et al. 2017). Prints the median strike error on the test hits 10 and 1 frames before
the hit, and their ratio (Table 1's trend; the twin issue's bar 0.75), for each seed alone and for the
final model (their mean, as in processed/predictions.parquet). Run from the repository root after
fit_uncertainty: `.venv/bin/python analysis/seed_average.py`.
"""

from pathlib import Path

import numpy as np

from pingpong.common.artifacts import read_table
from pingpong.curation.schemas import DATASET
from pingpong.learning.models import load_net
from pingpong.learning.schemas import PREDICTIONS
from pingpong.uncertainty.fit import estimator_hits


def main():
    dataset = read_table("processed/dataset.parquet", DATASET)
    predictions = read_table("processed/predictions.parquet", PREDICTIONS)
    seeds = Path("processed/models/final").glob("seed*.safetensors")
    stems = sorted(str(path.with_suffix("")) for path in seeds)
    hits = estimator_hits(dataset, predictions, [load_net(stem) for stem in stems])
    rows = hits.rows
    test, frames, truth = (rows["split"] == "test").to_numpy(), rows["frames_before_hit"].to_numpy(), \
        rows["strike_x"].to_numpy()
    candidates = [(Path(s).name, strike) for s, strike in zip(stems, hits.ensemble_strike, strict=True)]
    candidates += [("final (the seeds' mean)", rows["strike_x_pred"].to_numpy())]
    print(f"{test.sum() // 31} test hits\n| prediction | 10 frames before, cm | 1 frame before, cm | ratio |")
    print("|---|---:|---:|---:|")
    for name, strike in candidates:
        error = 100 * np.abs(strike - truth)
        at10, at1 = (np.median(error[test & (frames == f)]) for f in (10, 1))
        print(f"| {name} | {at10:.1f} | {at1:.1f} | {at1 / at10:.2f} |")


if __name__ == "__main__":
    main()
