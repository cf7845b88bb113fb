"""Timing helpers shared by the benchmark scripts (run as `python benchmarks/<name>.py`)."""

import importlib.util
import statistics
import subprocess
import sys
import time
from pathlib import Path


def best_time(fn, repeats: int) -> tuple[float, object]:
    """Fastest of `repeats` runs of fn() in s (the least disturbed on a shared machine), and its result."""
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return min(times), result


def fresh_process_medians(sides: dict[str, str], runs: int) -> dict[str, float]:
    """Median wall time (s) of `python -c code` for each side's code, in fresh processes, the sides
    alternated run by run so that the machine's drift falls on all of them alike."""
    seconds = {name: [] for name in sides}
    for _ in range(runs):
        for name, code in sides.items():
            start = time.perf_counter()
            subprocess.run([sys.executable, "-c", code], check=True)
            seconds[name].append(time.perf_counter() - start)
    return {name: statistics.median(s) for name, s in seconds.items()}


def module_at(revision: str, path: str):
    """The module at `path` (relative to the repository) as it was at git `revision`, imported as a module
    of its own: a benchmark's baseline run side by side with this checkout's."""
    source = subprocess.run(["git", "show", f"{revision}:{path}"], check=True, capture_output=True, text=True,
                            cwd=Path(__file__).resolve().parents[1]).stdout
    spec = importlib.util.spec_from_loader(f"{Path(path).stem}_{revision}", loader=None)
    module = importlib.util.module_from_spec(spec)
    exec(compile(source, f"{revision}:{path}", "exec"), module.__dict__)
    return module
