"""The workflow as a whole: memory against session length, a run with nothing to do, a clean run.

1. Memory: the frame-streaming stages (twin_camera, detection) on one session of R rallies and on one
   twice as long, side by side in two copies of the checkout; each job's peak RSS comes from its
   Snakemake `benchmark:` file. Frames are streamed, so twice the frames must not mean twice the memory.
2. Nothing to do: `snakemake` on the finished copy (DAG, params and code hashes checked, no job),
   against the baseline of starting Snakemake at all (`snakemake --version`) in the same run.
3. With --full: the whole default pipeline from clean in a fresh copy (`config/config.yaml`): wall
   time, and the peak RSS of the largest process (resource.getrusage over the finished children).

    PYTHONPATH=src python benchmarks/bench_pipeline.py [--rallies 4] [--full]
"""

import argparse
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from workflow_util import SNAKEMAKE, copy_checkout, snakemake, write_config  # noqa: E402

TARGET = "interim/detections/s00/cam0.parquet"
STREAMING = {"twin_camera": "benchmarks/results/twin_camera/s00_cam0.tsv",
             "detection": "benchmarks/results/detection/s00_cam0.tsv"}


def _frames(root: Path) -> int:
    return len(pd.read_parquet(root / TARGET, columns=["time_ns"]))


def memory_against_length(tmp: Path, rallies: int) -> pd.DataFrame:
    rows = []
    for n in (rallies, 2 * rallies):
        root = copy_checkout(tmp / f"r{n}")
        write_config(root, {"twin": {"n_sessions": 1, "rallies_per_session": n, "n_cameras": 2}})
        snakemake(root, TARGET)
        for rule, tsv in STREAMING.items():
            bench = pd.read_csv(root / tsv, sep="\t")
            rows.append({"rule": rule, "rallies": n, "frames": _frames(root),
                         "max_rss_mb": bench["max_rss"].iloc[0], "seconds": bench["s"].iloc[0]})
    return pd.DataFrame(rows)


def nothing_to_do(root: Path, repeats: int = 3) -> tuple[float, float]:
    def best(cmd):
        times = []
        for _ in range(repeats):
            start = time.perf_counter()
            subprocess.run(cmd, cwd=root, check=True, capture_output=True)
            times.append(time.perf_counter() - start)
        return min(times)
    base = best([*SNAKEMAKE, "--version"])
    noop = best([*SNAKEMAKE, "--cores", "2", TARGET, "--configfile", "config/test.yaml"])
    return noop, base


def whole_default_run(tmp: Path) -> tuple[float, float]:
    root = copy_checkout(tmp / "full")
    start = time.perf_counter()
    subprocess.run([*SNAKEMAKE, "--cores", "2"], cwd=root, check=True)
    wall = time.perf_counter() - start
    return wall, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024  # KiB -> MiB on Linux


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rallies", type=int, default=4)
    ap.add_argument("--full", action="store_true", help="also time the whole default pipeline from clean")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        mem = memory_against_length(tmp, a.rallies)
        print(mem.to_string(index=False))
        for rule, rows in mem.groupby("rule"):
            short, long = rows.iloc[0], rows.iloc[1]
            print(f"{rule}: {long.frames / short.frames:.2f}x the frames, "
                  f"{long.max_rss_mb / short.max_rss_mb:.2f}x the peak memory")
        noop, base = nothing_to_do(tmp / f"r{2 * a.rallies}")
        print(f"nothing to do: {noop:.2f} s, {noop / base:.1f}x starting Snakemake ({base:.2f} s)")
        if a.full:
            wall, peak = whole_default_run(tmp)
            print(f"whole default pipeline from clean: {wall / 60:.1f} min wall, peak RSS {peak:.0f} MiB")


if __name__ == "__main__":
    main()
