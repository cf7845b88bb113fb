"""Run the real workflow on a copy of this checkout, for the integration tests."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import yaml

from pingpong.common.config import schema_defaults
from pingpong.common.raw_ownership import OWNED

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
    """Modification time (ns) of every artifact under the data folders (not the twin's ownership records,
    which are bookkeeping: pingpong.common.raw_ownership)."""
    out = {}
    for folder in folders:
        for p in (root / folder).rglob("*"):
            if p.is_file() and p.name != ".gitkeep" and OWNED not in p.relative_to(root).as_posix():
                out[str(p.relative_to(root))] = p.stat().st_mtime_ns
    return out


def changed(before: dict, after: dict) -> set[str]:
    return {k for k in after if before.get(k) != after[k]}


# the robot's description, which the robot rules take as inputs
ROBOT_URDF, ROBOT_LIMITS = ROOT / "config/robot/iiwa14_ridgeback.urdf", ROOT / "config/robot/limits.yaml"
# every default of config/schema.yaml: what an empty config gives, and what the typed settings are built from
DEFAULTS = schema_defaults(ROOT / "config/schema.yaml")


def make_setup(clone: Path) -> Path:
    """`make setup` in `clone` (a fresh copy of the checkout) as a user runs it: the environment that
    `make run` installs first, not the tests' `test` extra. With uv's cache warm (the checkout's own setup
    filled it) the wheels are hardlinked from it: ~45 s, most of it byte-compiling. Returns `clone/.venv`."""
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH")}
    proc = subprocess.run(["make", "setup"], cwd=clone, env=env, capture_output=True, text=True)
    assert proc.returncode == 0, f"make setup failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-6000:]}"
    return clone / ".venv"


def open_in_browser(page: Path, shot: Path) -> str | None:
    """`page` in headless Chromium (Debian's package; .ci/run installs it), as the report's screenshot test
    (tests/test_pipeline_end_to_end.py) opens it: a 1280x900 screenshot written to `shot`, and the page's DOM
    once its scripts ran (returned). None where there is no browser."""
    browser = shutil.which("chromium")
    if browser is None:
        return None
    args = [browser, "--headless", "--no-sandbox", "--disable-gpu", "--window-size=1280,900",
            "--virtual-time-budget=5000"]
    subprocess.run([*args, f"--screenshot={shot}", page.as_uri()], check=True, capture_output=True,
                   timeout=120)
    return subprocess.run([*args, "--dump-dom", page.as_uri()], check=True, capture_output=True, text=True,
                          timeout=120).stdout
