"""The k-NN error regressor's neighbour search: exact brute force in blocks (torch) against scipy's cKDTree.

Rows shaped like the default run's frame features (79 standardised columns with low-dimensional
structure; 17k fitting rows, 24k query rows, k = 10), both searches in one run on the same rows and on
one thread each (as a workflow job runs them).

    PYTHONPATH=src python benchmarks/bench_knn.py [--fit 17000] [--query 24000]
"""

import argparse

import numpy as np
import torch
from scipy.spatial import cKDTree
from timing import best_time

from pingpong.uncertainty.knn import nearest_rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fit", type=int, default=17_000)
    ap.add_argument("--query", type=int, default=24_000)
    ap.add_argument("--k", type=int, default=10)
    a = ap.parse_args()
    torch.set_num_threads(1)
    rng = np.random.default_rng(0)
    mixing = rng.normal(size=(10, 79))
    reference, queries = (rng.normal(size=(n, 10)) @ mixing + 0.3 * rng.normal(size=(n, 79))
                          for n in (a.fit, a.query))
    tree_s, (_, tree) = best_time(lambda: cKDTree(reference).query(queries, k=a.k), 1)
    brute_s, brute = best_time(lambda: nearest_rows(reference, queries, a.k), 2)
    print(f"| {a.fit} fitting rows, {a.query} queries, k = {a.k} | s |\n|---|---:|")
    print(f"| scipy cKDTree | {tree_s:.2f} |")
    print(f"| brute force in blocks (torch.cdist, topk) | {brute_s:.2f} |")
    print(f"| ratio (tree / brute force) | {tree_s / brute_s:.1f}x |")
    print(f"| queries whose neighbours differ | {int((brute != tree).any(axis=1).sum())} |")


if __name__ == "__main__":
    main()
