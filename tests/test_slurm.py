"""A slice of the workflow through SLURM (`--profile profiles/slurm`, snakemake-executor-plugin-slurm)
writes the same artifacts as the local run.

Needs a SLURM cluster that answers here; `.ci/slurm-up` starts a single-node one (Debian's munge,
slurmctld and slurmd) and `.ci/run` calls it. Without one the test skips, saying why.

Slice: twin_rig and twin_simulate (independent), then twin_optitrack, which reads both: 3 sbatch jobs
in two waves, so a SLURM job also reads what other SLURM jobs wrote.
"""

import json
import re
import shutil
import subprocess
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from workflow_util import copy_checkout, snakemake, write_config

from pingpong.common.raw_ownership import OWNED

pytestmark = pytest.mark.slow

TINY = {"twin": {"n_sessions": 1, "rallies_per_session": 2, "n_cameras": 2, "width": 160, "height": 120}}
TARGETS = ["raw/twin_truth/rig.json", "raw/sessions/s00/optitrack.mcap"]
RULES = {"twin_rig", "twin_simulate", "twin_optitrack"}
EXPECTED = {
    "raw/twin_truth/rig.json",
    "raw/sessions/s00/optitrack.mcap",
    *(f"raw/twin_truth/s00/{t}.parquet"
      for t in ("ball", "shots", "events", "people", "paddles", "strike_oracle")),
}
SUBMITTED = re.compile(r"Job \d+ has been submitted with SLURM jobid (\d+) \(log: (\S+)\)\.")


def _run(cmd, timeout=20) -> subprocess.CompletedProcess:
    try:
        return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return subprocess.CompletedProcess(cmd, 124, "", f"timed out after {timeout} s")


@pytest.fixture(scope="module")
def cluster() -> dict:
    """The cluster's default partition and how to ask it about jobs; skips when there is none."""
    if shutil.which("sinfo") is None:
        pytest.skip("no SLURM here (sinfo not on PATH); .ci/slurm-up starts a single-node cluster")
    proc = _run(["sinfo", "-h", "-o", "%P %a %t"])
    if proc.returncode != 0:
        pytest.skip(f"the SLURM cluster does not answer (sinfo: {proc.stderr.strip()}); run .ci/slurm-up")
    rows = [line.split() for line in proc.stdout.splitlines() if line.strip()]
    usable = [r for r in rows if r[1] == "up" and r[2] in ("idle", "mix", "alloc")]
    if not usable:
        pytest.skip(f"no SLURM partition is up with a usable node (sinfo: {proc.stdout.strip()!r})")
    default = [r[0].rstrip("*") for r in usable if r[0].endswith("*")]
    # Without slurmdbd (the single-node test cluster) `sacct` fails: job states then come from squeue,
    # which keeps finished jobs for MinJobAge seconds (300 on that cluster).
    sacct = _run(["sacct", "-n", "-X", "-S", "now"]) if shutil.which("sacct") else None
    return {"partition": default[0] if default else usable[0][0].rstrip("*"),
            "status_command": "sacct" if sacct is not None and sacct.returncode == 0 else "squeue"}


def _slurm_args(cluster: dict) -> list[str]:
    return [
        "--profile", "profiles/slurm",
        # the plugin finds the default partition itself; name it anyway, for clusters without one
        "--set-resources", *(f"{rule}:slurm_partition={cluster['partition']}" for rule in sorted(RULES)),
        "--slurm-status-command", cluster["status_command"],
        # Status checks: the plugin waits this long after a check that saw a job finish (or no job
        # at all), and 10 s more after each check that saw none finish: checks 4, 18, 42 s after a
        # submission. A job here takes 9-14 s (Snakemake starts twice in it: the batch script and
        # its srun step), so each of the two waves is seen done at 18 s; with 1 s, at 12 or 33 s.
        "--slurm-init-seconds-before-status-checks", "4", "--seconds-between-status-checks", "4",
        # keep the SLURM logs of successful jobs too: they show that the jobs ran under SLURM
        "--slurm-keep-successful-logs",
    ]


def _artifacts(root: Path) -> dict[str, Path]:
    files = (root / "raw").rglob("*")
    return {str(p.relative_to(root)): p for p in files if p.is_file() and p.name != ".gitkeep"}


def test_slurm_run_matches_the_local_run(cluster, tmp_path):
    local = copy_checkout(tmp_path / "local")
    slurm = copy_checkout(tmp_path / "slurm")
    for root in (local, slurm):
        write_config(root, TINY)
    # one after the other (side by side saves ~4 s of ~50 but slows the SLURM jobs towards the 18 s
    # status check below, past which a wave costs 24 s more)
    snakemake(local, *TARGETS)  # --cores 2, profiles/default
    proc = snakemake(slurm, *TARGETS, *_slurm_args(cluster))

    # SLURM ran every job of the slice: one sbatch per job, each with its SLURM log, which holds the
    # job's own Snakemake run of the rule
    log = proc.stdout + proc.stderr
    submitted = SUBMITTED.findall(log)
    assert len(submitted) == len(RULES), log[-4000:]
    assert "localrule" not in log  # nothing ran on the submitting host
    ran = set()
    for jobid, logfile in submitted:
        path = Path(logfile)
        assert path.is_file(), f"SLURM job {jobid}: no log {path}"
        assert path.parent.relative_to(slurm / ".snakemake/slurm_logs").parts[0].startswith("rule_")
        ran |= {rule for rule in RULES if f"rule {rule}:" in path.read_text()}
        assert "Finished jobid" in path.read_text(), path.read_text()[-3000:]
    assert ran == RULES

    # identical artifacts: the same tables, the same JSON, and in fact the same bytes, provenance
    # included (it holds input content hashes and relative paths, nothing of the host or folder)
    # and the twin's ownership records (pingpong.common.raw_ownership), one per job, alike
    a, b = _artifacts(local), _artifacts(slurm)
    records = {name for name in a if name.startswith(OWNED + "/")}
    assert set(a) == set(b) and set(a) - records == EXPECTED
    assert {Path(name).name.rsplit("-", 1)[0] for name in records} == RULES
    for name in sorted(a):
        if name.endswith(".parquet"):
            ta, tb = pq.read_table(a[name]), pq.read_table(b[name])
            assert ta.equals(tb), name
            assert ta.schema.metadata == tb.schema.metadata, name  # the provenance record
        elif name.endswith(".json"):
            assert json.loads(a[name].read_text()) == json.loads(b[name].read_text()), name
        assert a[name].read_bytes() == b[name].read_bytes(), name
