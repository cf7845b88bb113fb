"""The twin's strike oracle flown in session-wide batches against one draw set at a time, in one run.

Both sides re-draw the same shots with the same seed; the baseline flies each shot's draw set (n_draws
balls) alone, as the oracle did before it batched, so the ratio is what batching buys. With --before REV,
instead: this checkout's oracle beside oracle.py as it was at REV (git show), interleaved, each its best
round of CPU time; the two tables must be equal bit for bit.

    PYTHONPATH=src python benchmarks/bench_oracle.py [--rallies 3] [--draws 200] [--before HEAD~1]
"""

import argparse
import time

import numpy as np
from timing import best_time, module_at

from pingpong.common.seeding import rng_for
from pingpong.twin import oracle as this_oracle
from pingpong.twin.oracle import BATCH_DRAWS, session_oracle
from pingpong.twin.session import FaultRates, simulate_session

ORACLE = "src/pingpong/twin/oracle.py"


def against(records, revision: str, draws: int, rounds: int = 3) -> None:
    """This checkout's session_oracle beside `revision`'s: CPU time and equality of the tables."""
    sides = {revision: module_at(revision, ORACLE), "this checkout": this_oracle}
    best, tables = dict.fromkeys(sides, np.inf), {}
    for _ in range(rounds):
        for name, module in sides.items():
            t0 = time.process_time()
            tables[name] = module.session_oracle(records, rng_for(1, "oracle"), 0, draws)
            best[name] = min(best[name], time.process_time() - t0)
    print(f"| {len(records)} good shots, {draws} draws, best of {rounds} | CPU s | time / before's |\n"
          "|---|---:|---:|")
    for name, seconds in best.items():
        print(f"| {name} | {seconds:.2f} | {seconds / best[revision]:.3f} |")
    same = tables[revision].equals(tables["this checkout"])
    print(f"\ntables equal bit for bit: {same}")
    if not same:
        raise SystemExit("the oracle tables differ")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rallies", type=int, default=3)
    ap.add_argument("--draws", type=int, default=200)
    ap.add_argument("--before", help="compare with oracle.py at this revision instead")
    a = ap.parse_args()
    records = simulate_session(a.rallies, FaultRates(), rng_for(1, "bench")).records
    if a.before:
        return against(records, a.before, a.draws)

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
