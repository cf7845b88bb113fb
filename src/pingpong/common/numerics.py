"""The same floating-point results on any x86-64 machine: every job's numeric libraries pinned to one kernel
family and one thread, before they load.

Left to themselves, the libraries pick their kernels from the CPU they run on, and their threads from
its cores, and the kernels and thread splits sum in different orders. Measured on this project's Sapphire
Rapids runner (docs/performance.md, "The same results on any CPU"; `analysis/compare_runs.py`):
- OpenBLAS (numpy's and scipy's) picks SkylakeX kernels here; with Haswell's, `A.T @ A`, `x @ x`, lstsq
  and svd differ in the last bits; and `x @ x` differs between 1 and 2 threads (the split of the sum);
- numpy 2.4 dispatches its exp, log, power, arctan2, arccos, expm1, log1p and cbrt loops to AVX-512
  (X86_V4) where the CPU has it, to AVX2 elsewhere: 1-ulp differences;
- torch's own kernels dispatch on the CPU (ATen: AVX-512 here; MKL and oneDNN their own), and
  OpenCV's dispatched code too.
OpenBLAS's core type alone, and numpy's dispatch alone, changed the tiny run's twin (its rig in the last
bit, then its rallies: 48 hits kept against 47); ATen's and MKL's dispatch each changed trained weights.
What stays unpinned: glibc's libm (numpy's scalar and AVX2 paths of some functions call it), so two
machines agree bit for bit with the same venv on the same glibc.

The pin: every library at the AVX2 + FMA level (Haswell, 2013; every x86-64 server and laptop CPU since
Intel Haswell and AMD Zen has it) and at one thread of its own (parallelism comes from Snakemake's jobs;
torch's threads are the rule's, `pingpong.common.script.pin_threads`). The variables are read when each
library loads, so `pin_numerics` must run before numpy, scipy, torch or cv2 is imported: the stage script
calls it first. They override what the shell set: a job's numbers depend on the code and the config only.
On another architecture (ARM) or a CPU without AVX2 only the thread counts are pinned, and results follow
that machine's kernels.
"""

import os
import platform
import sys
from pathlib import Path

# One thread per library (their own pools; torch's intra-op threads are set per rule after import).
THREADS = {
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "OMP_NUM_THREADS": "1",
}
# One kernel family: the AVX2 + FMA level, which every x86-64 CPU with `REQUIRED_FLAGS` runs.
KERNELS = {
    "OPENBLAS_CORETYPE": "Haswell",  # numpy's and scipy's OpenBLAS (OpenBLAS's DYNAMIC_ARCH core names)
    "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",  # numpy >= 2.4's AVX-512 dispatch targets
    "ATEN_CPU_CAPABILITY": "avx2",  # torch's vectorised kernels (default | avx2 | avx512)
    "MKL_CBWR": "AVX2",  # MKL's conditional numerical reproducibility: one code path on any CPU
    "ONEDNN_MAX_CPU_ISA": "AVX2",  # torch's oneDNN
    # OpenCV's dispatched code, by its own names (`cv2.getCPUFeaturesLine()` marks them `?`)
    "OPENCV_CPU_DISABLE": "AVX512-SKX,AVX512-CLX,AVX512-ICL,AVX_VNNI",
}
REQUIRED_FLAGS = {"avx2", "fma"}
NUMERIC_MODULES = ("numpy", "scipy", "torch", "cv2")


def cpu_flags(cpuinfo: Path = Path("/proc/cpuinfo")) -> set[str]:
    """The first CPU's feature flags (Linux); empty where unreadable."""
    try:
        for line in cpuinfo.read_text().splitlines():
            if line.startswith("flags"):
                return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


def pinned_environment(machine: str | None = None, flags: set[str] | None = None) -> dict[str, str]:
    """The variables pinned on this machine: thread counts always, the kernel family on an x86-64 CPU
    with AVX2 and FMA."""
    machine = platform.machine() if machine is None else machine
    flags = cpu_flags() if flags is None else flags
    x86_avx2 = machine.lower() in ("x86_64", "amd64") and REQUIRED_FLAGS <= flags
    return {**THREADS, **(KERNELS if x86_avx2 else {})}


def pin_numerics(environ=os.environ) -> dict[str, str]:
    """Set the pinned variables in `environ` (this process's, inherited by its children); refuse when a
    numeric library is loaded already (it read its variables then)."""
    loaded = [m for m in NUMERIC_MODULES if m in sys.modules]
    if loaded:
        raise RuntimeError(f"pin_numerics: {', '.join(loaded)} imported before the pin; call it first")
    pinned = pinned_environment()
    environ.update(pinned)
    return pinned
