"""The same numbers on any x86-64 CPU: `pingpong.common.numerics.pin_numerics` fixes every numeric
library's kernel family and threads before they load, whatever the machine (or the shell) would pick.

A machine of another CPU family is played here by the libraries' own overrides (OpenBLAS's core type,
numpy's dispatch, torch's CPU capability, thread counts): they make this machine compute as that one would.
"""

import json
import os
import subprocess
import sys

import pytest

from pingpong.common.numerics import KERNELS, THREADS, cpu_flags, pin_numerics, pinned_environment

# What the libraries chose and what they computed: matmul, dot (a threaded reduction), least squares and
# SVD through OpenBLAS, exp/log/arctan2 through numpy's dispatched loops, a GRU step and a sum in torch.
PROBE = """
import hashlib, json, sys
if sys.argv[1] == "pin":
    from pingpong.common.numerics import pin_numerics
    pin_numerics()
import cv2, numpy as np, scipy.linalg, threadpoolctl, torch
from numpy._core._multiarray_umath import __cpu_features__
rng = np.random.default_rng(0)
x, y, A = rng.normal(size=100_001) * 3, rng.normal(size=100_001), rng.normal(size=(300, 40))
torch.manual_seed(0)
gru, seq = torch.nn.GRU(39, 64, 2, batch_first=True), torch.randn(50, 31, 39)
def digest(*arrays):
    return hashlib.sha256(b"".join(np.ascontiguousarray(a).tobytes() for a in arrays)).hexdigest()
print(json.dumps({
    "blas": sorted({(i["architecture"], i["num_threads"]) for i in threadpoolctl.threadpool_info()
                    if i["internal_api"] == "openblas"}),
    "numpy_avx512": __cpu_features__["X86_V4"],
    "torch": torch.backends.cpu.get_cpu_capability(),
    "opencv": [f.strip("*") for f in cv2.getCPUFeaturesLine().split() if f.startswith("*") and "?" not in f],
    "blas_values": digest(A.T @ A, x @ x, np.linalg.lstsq(A, x[:300], rcond=None)[0],
                          np.linalg.svd(A, compute_uv=False), scipy.linalg.solve(A.T @ A, A.T @ x[:300])),
    "numpy_values": digest(np.exp(x), np.log(np.abs(x)), np.arctan2(x, y)),
    "torch_values": digest(gru(seq)[0].detach().numpy(), torch.from_numpy(x).float().sum().numpy()),
}))
"""
# Other machines, by their libraries' overrides: an AVX2-only CPU (Haswell/Zen), an older AVX one
# (Sandybridge), and one of another core count (one BLAS thread, where the libraries use all cores);
# this runner's own is SkylakeX, AVX-512.
OTHER_MACHINES = {
    "avx2": {"OPENBLAS_CORETYPE": "Haswell", "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",
             "ATEN_CPU_CAPABILITY": "avx2"},
    "sandybridge": {"OPENBLAS_CORETYPE": "Sandybridge", "ATEN_CPU_CAPABILITY": "default"},
    "threads": {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"},
}
X86_AVX2 = bool(pinned_environment().get("OPENBLAS_CORETYPE"))


def probe(mode: str, env: dict) -> dict:
    clean = {k: v for k, v in os.environ.items() if k not in {*KERNELS, *THREADS}}
    out = subprocess.run([sys.executable, "-c", PROBE, mode], env={**clean, **env}, check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out)


@pytest.mark.skipif(not X86_AVX2, reason="the kernel pin applies on x86-64 CPUs with AVX2 and FMA")
def test_pinned_libraries_compute_the_same_bits_as_on_other_cpus():
    here = probe("pin", {})
    assert here["blas"] == [["Haswell", 1]]
    assert not here["numpy_avx512"] and here["torch"] == "AVX2"
    assert not any(f.startswith(("AVX512", "AVX_VNNI")) for f in here["opencv"]), here["opencv"]
    for name, env in OTHER_MACHINES.items():
        assert probe("pin", env) == here, name


@pytest.mark.skipif(not X86_AVX2 or "avx512f" not in cpu_flags(), reason="needs an AVX-512 CPU to differ")
def test_unpinned_libraries_differ_between_cpus():
    """Without the pin the same probe changes with the CPU family and the threads: what the pin is for
    (and proof that the probe sees the libraries' choices)."""
    here = probe("free", {})
    for name, env in OTHER_MACHINES.items():
        if name == "threads" and os.cpu_count() == 1:
            continue  # one thread is this machine's own count
        other = probe("free", env)
        differ = [k for k in ("blas_values", "numpy_values", "torch_values") if other[k] != here[k]]
        assert differ, name


def test_only_threads_are_pinned_off_x86_or_without_avx2():
    assert pinned_environment("aarch64", {"avx2", "fma"}) == THREADS
    assert pinned_environment("x86_64", {"sse4_2", "avx"}) == THREADS
    assert pinned_environment("x86_64", {"avx2", "fma", "avx512f"}) == {**THREADS, **KERNELS}


def test_pin_refuses_once_a_library_has_loaded():
    import numpy  # noqa: F401  (loaded: its variables were read)

    with pytest.raises(RuntimeError, match="numpy"):
        pin_numerics({})
