"""Timing helper shared by the benchmark scripts (run as `python benchmarks/<name>.py`)."""

import time


def best_time(fn, repeats: int) -> tuple[float, object]:
    """Fastest of `repeats` runs of fn() in s (the least disturbed on a shared machine), and its result."""
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return min(times), result
