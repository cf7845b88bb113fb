"""Table 1 of the final model against the mean of its seeds: how much of the strike error is one seed's luck?

The uncertainty stage's ensemble members are the selected configuration refit on the training part with
seeds seed + member (member 0 is the final model itself, same seed, same weights). Their mean is a deep
ensemble's point prediction (Lakshminarayanan et al. 2017). Prints the median strike error on the test
hits 10 and 1 frames before the hit, and their ratio (Table 1's trend; the twin issue's bar 0.75), for the
final model, each member and the members' mean. Run from the repository root after fit_uncertainty:
`.venv/bin/python analysis/seed_average.py`.
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
    members = Path("processed/models/ensemble").glob("member*.safetensors")
    stems = sorted(str(path.with_suffix("")) for path in members)
    hits = estimator_hits(dataset, predictions, [load_net(stem) for stem in stems])
    rows = hits.rows
    test, frames, truth = (rows["split"] == "test").to_numpy(), rows["frames_before_hit"].to_numpy(), \
        rows["strike_x"].to_numpy()
    candidates = [("final", rows["strike_x_pred"].to_numpy())]
    candidates += [(Path(s).name, strike) for s, strike in zip(stems, hits.ensemble_strike, strict=True)]
    candidates += [("mean of the members", hits.ensemble_strike.mean(axis=0))]
    print(f"{test.sum() // 31} test hits\n| prediction | 10 frames before, cm | 1 frame before, cm | ratio |")
    print("|---|---:|---:|---:|")
    for name, strike in candidates:
        error = 100 * np.abs(strike - truth)
        at10, at1 = (np.median(error[test & (frames == f)]) for f in (10, 1))
        print(f"| {name} | {at10:.1f} | {at1:.1f} | {at1 / at10:.2f} |")


if __name__ == "__main__":
    main()
