"""A killed run: the temporary files of killed writes are swept when their job starts again, artifacts get
the modes of the process's umask, and a job killed mid-write restarts (as the README says: `snakemake
--unlock`, then the same command) to the bytes of an uninterrupted run."""

import os
import signal
import stat
import subprocess
import time
from pathlib import Path

import pytest
from conftest import TINY_CONFIG
from workflow_util import SNAKEMAKE, copy_checkout, snakemake

from pingpong.common.atomic import (
    atomic_dir,
    atomic_path,
    is_temporary_of,
    sweep_temporaries,
    write_text_atomic,
)
from pingpong.common.script import Named, StageContext, sweep_outputs


@pytest.fixture
def umask():
    """Set the process's umask for one test (the forked writers and Snakemake inherit it)."""
    before = os.umask(0o022)
    yield lambda mask: os.umask(mask)
    os.umask(before)


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


@pytest.mark.parametrize("mask", [0o022, 0o002, 0o077])
def test_artifacts_get_the_umask_modes(tmp_path, umask, mask):
    umask(mask)
    write_text_atomic(tmp_path / "a" / "table.md", "x")
    with atomic_path(tmp_path / "b.bin") as tmp:
        tmp.write_bytes(b"y")
    with atomic_dir(tmp_path / "folder") as tmp:
        (tmp / "f.json").write_text("{}")
    assert _mode(tmp_path / "a" / "table.md") == _mode(tmp_path / "b.bin") == 0o666 & ~mask
    assert _mode(tmp_path / "folder") == _mode(tmp_path / "a") == 0o777 & ~mask
    assert _mode(tmp_path / "folder" / "f.json") == 0o666 & ~mask


_NEVER_EXITED = []  # writes left open as after SIGKILL (a collected one would clean up after itself)


def _killed_write(path: Path, writer=atomic_path) -> Path:
    """What a write of `path` killed mid-way leaves: its temporary file or folder, the block never done."""
    _NEVER_EXITED.append(writer(path))
    return Path(_NEVER_EXITED[-1].__enter__())


def test_sweep_removes_only_the_outputs_temporaries(tmp_path):
    out = tmp_path / "cam0.mcap"
    left = _killed_write(out)
    left_dir = _killed_write(tmp_path / "openpose", atomic_dir)
    (left_dir / "x.json").write_text("{}")
    others = [tmp_path / ".cam0.mcap.notours.tmp",  # not the random part's length (8)
              tmp_path / ".cam0.mcap.abcd1234.tmp.keep",  # not the suffix
              tmp_path / ".cam1.mcap.abcd1234.tmp",  # another output's
              tmp_path / "cam0.mcap.abcd1234.tmp",  # not hidden: not ours
              tmp_path / ".cam0.mcapXabcd1234.tmp"]
    for p in others:
        p.write_bytes(b"keep")
    assert is_temporary_of(left, out) and not any(is_temporary_of(p, out) for p in others)
    outputs = Named(mcap=str(out), folder=str(tmp_path / "openpose"))
    ctx = StageContext("twin_camera", Named(), outputs, {}, None)
    sweep_outputs(ctx)
    assert not left.exists() and not left_dir.exists()
    assert all(p.read_bytes() == b"keep" for p in others)
    assert sweep_temporaries(tmp_path / "missing" / "x.parquet") == []


def test_sweep_takes_names_with_glob_characters_literally(tmp_path):
    out = tmp_path / "s[0]*.parquet"
    left = _killed_write(out)
    bystander = tmp_path / ".s0x.parquet.abcd1234.tmp"
    bystander.write_bytes(b"keep")
    assert sweep_temporaries(out) == [left] and bystander.exists()


def _temporaries(root: Path) -> list[Path]:
    folders = ("raw", "interim", "processed", "reports")
    return [p for folder in folders for p in (root / folder).rglob(".*.tmp")]


def _kill_when_writing(cmd, root: Path, target: Path, umask_value: int, timeout_s=180) -> Path:
    """Start `cmd`; once the write of `target` is under way (its temporary holds 5 MB), SIGKILL Snakemake and
    its jobs together; returns the temporary file the killed write left."""
    proc = subprocess.Popen(cmd, cwd=root, env={**os.environ, "PYTHONPATH": str(root / "src")},
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
                            umask=umask_value)
    deadline = time.monotonic() + timeout_s
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            temps = [p for p in target.parent.glob(f".{target.name}.*.tmp") if p.stat().st_size > 5e6]
            if temps:
                return temps[0]
            time.sleep(0.05)
        raise AssertionError(f"{target}'s write never started (snakemake exit {proc.poll()})")
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


def test_a_job_killed_mid_write_restarts_to_the_uninterrupted_bytes(tiny_run, tmp_path, umask):
    """One twin camera of the tiny run (~15 s of rendering), killed while writing its MCAP, restarted."""
    umask(0o022)
    root = copy_checkout(tmp_path)
    name = "raw/sessions/s00/cam0.mcap"
    target = root / name
    cmd = [*SNAKEMAKE, "--cores", "1", name, "--configfile", TINY_CONFIG]
    left = _kill_when_writing(cmd, root, target, 0o022)
    time.sleep(0.5)
    assert left.exists() and not target.exists()  # the killed write: its temporary, no artifact
    relock = snakemake(root, name, configfile=TINY_CONFIG, check=False)  # the kill left Snakemake's lock
    assert relock.returncode != 0 and "--unlock" in relock.stderr
    snakemake(root, "--unlock", configfile=TINY_CONFIG)
    snakemake(root, name, configfile=TINY_CONFIG)
    assert target.read_bytes() == (tiny_run / name).read_bytes()
    assert _temporaries(root) == []
    assert _mode(target) == 0o644 and _mode(target.parent) == 0o755  # readable by the group (umask 022)
