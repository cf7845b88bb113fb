"""The workflow's artifacts do not depend on the CPU they were computed on: the twin's truth, which the
kernel family changed most (docs/performance.md, "The same results on any CPU"), made again under other
machines' library choices is byte for byte the tiny run's."""

import hashlib
import os
import subprocess

import pytest
from conftest import TINY_CONFIG, TINY_RUN
from test_numerics import OTHER_MACHINES, X86_AVX2
from workflow_util import SNAKEMAKE, copy_checkout

# Without the pin, numpy's AVX-512 loops and OpenBLAS's Haswell kernels each changed every one of these
# (the rig's camera poses in the last bit, then the rallies: 48,632 ball rows against 48,631).
TWIN_TRUTH = ["raw/twin_truth/rig.json"] + [f"raw/twin_truth/s00/{name}.parquet" for name in
                                            ("ball", "shots", "events", "people", "paddles", "strike_oracle")]


@pytest.mark.slow
@pytest.mark.skipif(not X86_AVX2, reason="the kernel pin applies on x86-64 CPUs with AVX2 and FMA")
def test_twin_truth_is_the_same_under_another_cpus_libraries(tiny_run, tmp_path):
    assert TINY_RUN["twin"]["n_sessions"] >= 1
    other = copy_checkout(tmp_path)
    machine = {k: v for name in ("sandybridge", "threads") for k, v in OTHER_MACHINES[name].items()}
    env = {**os.environ, **machine, "PYTHONPATH": str(other / "src")}
    proc = subprocess.run([*SNAKEMAKE, "--cores", "2", *TWIN_TRUTH, "--configfile", TINY_CONFIG], cwd=other,
                          env=env, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-4000:]
    digest = lambda path: hashlib.sha256(path.read_bytes()).hexdigest()  # noqa: E731
    differ = [name for name in TWIN_TRUTH if digest(other / name) != digest(tiny_run / name)]
    assert not differ, differ
