"""Where do two runs of the workflow part? Every artifact of two run folders compared, byte for byte, in
the order the first run wrote them (its files' modification times: the DAG's order as it ran), so the
first difference names the stage that made it and everything after it is its consequence.

For a table that differs: its row counts and, column by column, how many values differ and by how much
(the size of a rounding difference against a real one). Used for docs/performance.md's determinism
section (runs of the tiny config under different BLAS core types and thread counts):

    .venv/bin/python analysis/compare_runs.py RUN_A RUN_B [--all]
"""

import argparse
import hashlib
import sys
from pathlib import Path

import numpy as np
import pandas as pd

DATA_FOLDERS = ("raw", "interim", "processed", "reports")


def artifacts_in_run_order(root: Path) -> list[str]:
    """Every artifact under the data folders, relative to `root`, oldest first."""
    files = [p for folder in DATA_FOLDERS for p in (root / folder).rglob("*")
             if p.is_file() and p.name != ".gitkeep"]
    return [str(p.relative_to(root)) for p in sorted(files, key=lambda p: (p.stat().st_mtime_ns, str(p)))]


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def table_difference(a: Path, b: Path) -> str:
    """A line per differing column of two parquet tables (or their row counts where those differ)."""
    ta, tb = pd.read_parquet(a), pd.read_parquet(b)
    if len(ta) != len(tb):
        return f"rows {len(ta)} vs {len(tb)}"
    lines = []
    for col in ta.columns:
        if col not in tb.columns:
            lines.append(f"{col}: only in the first")
            continue
        x, y = ta[col].to_numpy(), tb[col].to_numpy()
        if x.dtype.kind == "f" and y.dtype.kind == "f":
            differ = ~((x == y) | (np.isnan(x) & np.isnan(y)))
            if differ.any():
                gap = np.abs(x[differ] - y[differ])
                scale = np.maximum(np.abs(x[differ]), np.abs(y[differ]))
                lines.append(f"{col}: {differ.sum()} of {len(x)} differ, max |d| {np.nanmax(gap):.3g}, "
                             f"max relative {np.nanmax(gap / np.where(scale > 0, scale, 1)):.3g}")
        elif x.dtype == object or y.dtype == object:
            differ = np.array([repr(u) != repr(v) for u, v in zip(x, y, strict=True)])
            if differ.any():
                lines.append(f"{col}: {differ.sum()} of {len(x)} differ")
        elif not np.array_equal(x, y):
            lines.append(f"{col}: {(x != y).sum()} of {len(x)} differ")
    return "; ".join(lines) or "same values, different bytes (metadata)"


def compare(first: Path, second: Path) -> list[tuple[str, str]]:
    """(artifact, how it differs) for every artifact that is missing from the second run or differs."""
    out = []
    for name in artifacts_in_run_order(first):
        other = second / name
        if not other.is_file():
            out.append((name, "missing in the second run"))
        elif digest(first / name) != digest(other):
            detail = table_difference(first / name, other) if name.endswith(".parquet") else "bytes differ"
            out.append((name, detail))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("first", type=Path)
    ap.add_argument("second", type=Path)
    ap.add_argument("--all", action="store_true", help="every differing artifact, not the first 15")
    a = ap.parse_args(argv)
    differences = compare(a.first, a.second)
    n = len(artifacts_in_run_order(a.first))
    print(f"{len(differences)} of {n} artifacts differ")
    for name, detail in differences if a.all else differences[:15]:
        print(f"{name}: {detail}")
    tables = [d for d in differences if d[0].startswith("reports/tables/")]
    print(f"report tables that differ: {len(tables)}" + "".join(f"\n  {name}" for name, _ in tables))
    return 1 if differences else 0


if __name__ == "__main__":
    sys.exit(main())
