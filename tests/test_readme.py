"""The README as the user's document (issue 39): short, its results block the generator's output for a stated
commit, and every command of its shell blocks run as written (the lab section's by test_lab_markerless.py)."""

import os
import re
import signal
import subprocess
import time
from pathlib import Path

import pytest

from pingpong.reports.summary import SummaryError, run_tables, summary_markdown

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DEFAULT_RUN = ROOT / "docs/results/default_run.md"
LAB_SECTION = "## Bringing your lab's recordings"


def results_block(text: str) -> str:
    begin, end = "<!-- results: docs/results/default_run.md -->\n", "<!-- end results -->\n"
    match = re.search(re.escape(begin) + "(.*?)" + re.escape(end), text, re.S)
    assert match, "the README's results block (between its two markers) is missing"
    return match.group(1)


def readme_commands() -> list[str]:
    """Every command line of the README's ```bash blocks outside the lab section, comments stripped."""
    text = README.read_text()
    before, after = text.split(LAB_SECTION, 1)
    outside = before + after.split("\n## ", 1)[1]
    return [line for block in re.findall(r"```bash\n(.*?)```", outside, re.S)
            for line in (ln.split("  #")[0].strip() for ln in block.splitlines()) if line]


def test_the_readme_is_short():
    assert len(README.read_text().splitlines()) <= 250


def test_results_block_is_the_generated_summary():
    """The README quotes the default run's summary whole, as analysis/default_run_summary.py wrote it."""
    assert results_block(README.read_text()) == DEFAULT_RUN.read_text()
    assert re.match(r"Results of the run of commit [0-9a-f]{7,40} ", DEFAULT_RUN.read_text())


def test_the_summary_rule_writes_the_tables_figures(tiny_run):
    """rule all wrote reports/summary.md; it is the library's summary of that run's tables and quotes them."""
    text = (tiny_run / "reports/summary.md").read_text()
    commit = re.match(r"Results of the run of commit (.*?) \(its", text).group(1)
    seed = int(re.search(r"^seed: (\d+)", (tiny_run / "config/config.yaml").read_text(), re.M).group(1))
    tables = run_tables(tiny_run)
    assert text == summary_markdown(**tables, commit=commit, seed=seed)
    curation = tables["curation"].set_index("decision")["candidates"]
    assert f"| hits kept | {curation['kept']} of {curation.sum()} candidates" in text
    servo = tables["robot"].query("controller == 'servo' and region == 'all'").iloc[0]
    assert f"| robot: visual servoing alone | {servo.hits} of {servo.total} " in text


def test_a_table_without_its_columns_is_named(tiny_run):
    tables = run_tables(tiny_run)
    tables["robot"] = tables["robot"].drop(columns="hits")
    with pytest.raises(SummaryError, match=r"robot: expected columns \['hits'\]"):
        summary_markdown(**tables, commit="abc1234", seed=0)


def kill_a_run(root: Path, env: dict) -> None:
    """A run killed with SIGKILL while it holds the folder's lock, as a lost session leaves it."""
    proc = subprocess.Popen([".venv/bin/snakemake", "--forcerun", "report_summary"], cwd=root, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    locks = root / ".snakemake/locks"
    deadline = time.monotonic() + 120
    while not (locks.is_dir() and any(locks.iterdir())) and proc.poll() is None \
            and time.monotonic() < deadline:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    assert any(locks.iterdir()), "the killed run left no lock to recover from"


def test_every_readme_command_runs(tiny_run, tmp_path):
    """Each command as written, in the tiny run's folder with the tiny config (a profile in
    SNAKEMAKE_PROFILE, what a user's profiles/default does): `make run` finds the run complete, the dry runs
    list their jobs (the SLURM profile's too), `make report` writes the page, and after a killed run the
    rerun is refused until `--unlock`, then finishes. `make test` is this suite: its command is checked."""
    if not (tiny_run / ".venv").exists():
        (tiny_run / ".venv").symlink_to(ROOT / ".venv")
    profile = tmp_path / "tiny_profile"
    profile.mkdir()
    (profile / "config.yaml").write_text("cores: 2\nconfigfile: [config/test/tiny.yaml]\n"
                                         "rerun-incomplete: true\n")
    env = {**os.environ, "PYTHONPATH": str(tiny_run / "src"), "SNAKEMAKE_PROFILE": str(profile)}

    def run(command):
        return subprocess.run(command, shell=True, cwd=tiny_run, env=env, capture_output=True, text=True)

    commands = readme_commands()
    assert {"make run", "make test", ".venv/bin/snakemake --unlock"} <= set(commands)
    # make run would install over the shared .venv if it were out of date: refuse rather than do that
    assert run("make -q setup").returncode == 0, ".venv is out of date for this checkout: run make setup"
    for command in commands:
        if command == "make test":
            assert ".venv/bin/python -m pytest" in run("make -n test").stdout
            continue
        if command == ".venv/bin/snakemake --unlock":
            kill_a_run(tiny_run, env)
            refused = run(".venv/bin/snakemake")  # a dry run ignores the lock; the run itself must not
            assert refused.returncode != 0 and "lock" in (refused.stdout + refused.stderr).lower()
        proc = run(command)
        assert proc.returncode == 0, f"{command} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-6000:]}"
        if command == "make run":
            assert "Nothing to be done" in proc.stdout + proc.stderr
    assert (tiny_run / "reports/report.html").is_file() and (tiny_run / "reports/summary.md").is_file()
