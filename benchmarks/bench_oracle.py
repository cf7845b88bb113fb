"""The twin's strike oracle flown in session-wide batches against one draw set at a time, in one run.

Both sides re-draw the same shots with the same seed; the baseline flies each shot's draw set (n_draws
balls) alone, as the oracle did before it batched, so the ratio is what batching buys.

    PYTHONPATH=src python benchmarks/bench_oracle.py [--rallies 3] [--draws 200]
"""

import argparse

import numpy as np
from timing import best_time

from pingpong.common.seeding import rng_for
from pingpong.twin.oracle import BATCH_DRAWS, session_oracle
from pingpong.twin.session import FaultRates, simulate_session


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rallies", type=int, default=3)
    ap.add_argument("--draws", type=int, default=200)
    a = ap.parse_args()
    records = simulate_session(a.rallies, FaultRates(), rng_for(1, "bench")).records

    def oracle(batch):
        return session_oracle(records, rng_for(1, "oracle"), 0, a.draws, batch_draws=batch)

    alone_s, alone = best_time(lambda: oracle(a.draws), 2)
    batched_s, batched = best_time(lambda: oracle(BATCH_DRAWS), 2)
    gap = np.nanmax(np.abs(alone.oracle_mean_x - batched.oracle_mean_x))
    flips = int(np.abs(alone.oracle_n - batched.oracle_n).sum())
    print(f"| {len(records)} good shots, {a.draws} draws | s |\n|---|---:|")
    print(f"| one draw set at a time | {alone_s:.2f} |")
    print(f"| batches of {BATCH_DRAWS} draws | {batched_s:.2f} |")
    print(f"| ratio (one at a time / batched) | {alone_s / batched_s:.1f}x |")
    print(f"| largest difference in oracle_mean_x | {gap * 1e3:.3f} mm |")
    print(f"| good draws that differ (summed over frames) | {flips} |")


if __name__ == "__main__":
    main()
