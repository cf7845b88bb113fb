"""What the raw/ ownership check costs at each start of Snakemake (pingpong.common.raw_ownership), on a
finished run's raw/: with its stat cache (every later start), without it (the first start after the twin
wrote raw/: every file hashed), beside the floor of listing and stat-ing the same files, rounds alternated.

    python benchmarks/bench_raw_check.py RUN_ROOT [--rounds 3]
"""

import argparse
import os
from pathlib import Path

from timing import best_time

from pingpong.common import raw_ownership


def list_and_stat(root: Path) -> int:
    """The floor: every file under raw/ found and stat-ed, nothing read."""
    count = 0
    for folder, _dirs, files in os.walk(root / "raw"):
        for name in files:
            os.lstat(os.path.join(folder, name))
            count += 1
    return count


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", type=Path, help="a finished run's folder (its raw/ and .snakemake/)")
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    cache = a.root / raw_ownership.STAT_CACHE
    floor, cold, warm = [], [], []
    for _ in range(a.rounds):
        floor.append(best_time(lambda: list_and_stat(a.root), 1)[0])
        cache.unlink(missing_ok=True)
        cold.append(best_time(lambda: raw_ownership.check(a.root), 1)[0])
        warm.append(best_time(lambda: raw_ownership.check(a.root), 1)[0])
    files = list_and_stat(a.root)
    size = sum(f.stat().st_size for f in (a.root / "raw").rglob("*") if f.is_file())
    print(f"{files} files, {size / 1e9:.2f} GB under raw/")
    print(f"listing and stat: {min(floor):.2f} s; check with the stat cache {min(warm):.2f} s "
          f"({min(warm) / min(floor):.2f}x); without it {min(cold):.2f} s ({min(cold) / min(floor):.1f}x, "
          f"{size / 1e9 / min(cold):.2f} GB/s hashed)")


if __name__ == "__main__":
    main()
