"""Run the real workflow on a copy of this checkout, for the integration tests."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import yaml

from pingpong.common.config import schema_defaults

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = [sys.executable, "-m", "snakemake"]


def copy_checkout(dest: Path) -> Path:
    """The tracked and untracked-but-not-ignored files of this checkout, copied to `dest`."""
    files = subprocess.run(["git", "ls-files", "-co", "--exclude-standard"], cwd=ROOT, check=True,
                           capture_output=True, text=True).stdout.split()
    for name in files:
        if (ROOT / name).is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / name, dest / name)
    return dest


def write_config(root: Path, config: dict, name="test.yaml") -> Path:
    path = root / "config" / name
    path.write_text(yaml.safe_dump(config))
    return path


def snakemake(root: Path, *args, configfile="config/test.yaml", check=True) -> subprocess.CompletedProcess:
    cmd = [*SNAKEMAKE, "--cores", "2", *args, "--configfile", configfile]  # --configfile takes a list: last
    # the jobs import the package from the copy, so that edits to it count
    env = {**os.environ, "PYTHONPATH": str(root / "src")}
    proc = subprocess.run(cmd, cwd=root, capture_output=True, text=True, env=env)
    if check and proc.returncode != 0:
        raise AssertionError(f"snakemake failed ({proc.returncode}):\n{proc.stderr[-6000:]}")
    return proc


def mtimes(root: Path, folders=("raw", "interim", "processed", "reports")) -> dict[str, int]:
    """Modification time (ns) of every artifact under the data folders."""
    out = {}
    for folder in folders:
        for p in (root / folder).rglob("*"):
            if p.is_file() and p.name != ".gitkeep":
                out[str(p.relative_to(root))] = p.stat().st_mtime_ns
    return out


def changed(before: dict, after: dict) -> set[str]:
    return {k for k in after if before.get(k) != after[k]}


# the robot's description, which the robot rules take as inputs
ROBOT_URDF, ROBOT_LIMITS = ROOT / "config/robot/iiwa14_ridgeback.urdf", ROOT / "config/robot/limits.yaml"
# every default of config/schema.yaml: what an empty config gives, and what the typed settings are built from
DEFAULTS = schema_defaults(ROOT / "config/schema.yaml")
