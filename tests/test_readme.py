"""The README as the user's document (issue 39): short, its results block the generator's output for a stated
commit, and every command of its shell blocks run as written, in the README's order, in the environment a
user's `make setup` makes (issue 50: not the tests' `test` extra, which hid what `make run` does not
install); the lab section's commands on recordings by test_lab_markerless.py."""

import os
import re
import signal
import subprocess
import textwrap
import time
from pathlib import Path

import cv2
import pytest
from workflow_util import copy_checkout, make_setup, open_in_browser

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


def section_commands(text: str) -> list[str]:
    """Every command line of the ```bash blocks in `text`, comments stripped."""
    return [line for block in re.findall(r"```bash\n(.*?)```", text, re.S)
            for line in (ln.split("  #")[0].strip() for ln in block.splitlines()) if line and line[0] != "#"]


def lab_section() -> str:
    return README.read_text().split(LAB_SECTION, 1)[1].split("\n## ", 1)[0]


def readme_commands() -> list[str]:
    """Every command line of the README's ```bash blocks in its order; of the lab section only its `make`
    commands (its others need a lab's recordings: test_lab_markerless.py runs them)."""
    return [command for section in re.split(r"\n(?=## )", README.read_text())
            for command in section_commands(section)
            if not section.startswith(LAB_SECTION) or command.startswith("make ")]


@pytest.fixture(scope="module")
def user_clone(tmp_path_factory):
    """A fresh clone after `make setup`: the environment that the quick start's `make run` and the lab
    walkthrough's first command make, so that a README command needing what no README step installs fails."""
    clone = copy_checkout(tmp_path_factory.mktemp("fresh_clone"))
    make_setup(clone)
    return clone


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


def run_in(root: Path, env: dict):
    def run(command: str) -> subprocess.CompletedProcess:
        return subprocess.run(command, shell=True, cwd=root, env=env, capture_output=True, text=True)
    return run


def test_the_lab_walkthrough_sets_up_a_fresh_clone(user_clone):
    """The lab's setup without the twin: a fresh clone has no .venv, so step 3 starts with `make setup`
    (user_clone ran that command first; here it is run again as written and finds nothing to do), then the
    config check passes on the README's config and the dry run stops before any job naming the recordings
    this clone lacks, not something the environment lacks. Run before the commands below, which add to it."""
    commands = section_commands(lab_section())
    assert commands[0] == "make setup", f"the lab walkthrough's first command is {commands[0]!r}"
    [config] = re.findall(r"```yaml\n(.*?)```", lab_section(), re.S)
    (user_clone / "config/lab.yaml").write_text(textwrap.dedent(config))
    run = run_in(user_clone, {**os.environ, "PYTHONPATH": str(user_clone / "src")})
    for command in commands:
        proc = run(command)
        out = proc.stdout + proc.stderr
        if ".venv/bin/snakemake" in command:
            assert proc.returncode != 0 and "raw/sessions/lab01" in out, out[-6000:]
            break  # the run itself stops likewise
        assert proc.returncode == 0, f"{command} failed:\n{out[-6000:]}"


@pytest.fixture(scope="module")
def readme_run(tiny_run, user_clone, tmp_path_factory):
    """Each README command as written, in the tiny run's folder with the tiny config (a profile in
    SNAKEMAKE_PROFILE, what a user's profiles/default does) and its .venv the fresh clone's: (command,
    process) in the README's order. A SIGKILLed run comes before `--unlock`: the rerun is (command, process)
    too, under the name "rerun before --unlock"."""
    venv = tiny_run / ".venv"
    if venv.is_symlink():
        venv.unlink()
    venv.symlink_to(user_clone / ".venv")
    profile = tmp_path_factory.mktemp("tiny_profile")
    (profile / "config.yaml").write_text("cores: 2\nconfigfile: [config/test/tiny.yaml]\n"
                                         "rerun-incomplete: true\n")
    env = {**os.environ, "PYTHONPATH": str(tiny_run / "src"), "SNAKEMAKE_PROFILE": str(profile)}
    run = run_in(tiny_run, env)
    assert run("make -q setup").returncode == 0, "make run would reinstall the fresh clone's environment"
    done = []
    for command in readme_commands():
        if command == "make test":  # this suite, in the `test` extra: only its command is checked
            done.append(("make -n test", run("make -n test")))
            continue
        if command == ".venv/bin/snakemake --unlock":
            kill_a_run(tiny_run, env)
            done.append(("rerun before --unlock", run(".venv/bin/snakemake")))  # a dry run ignores the lock
        done.append((command, run(command)))
    return done


def test_every_readme_command_runs(readme_run, tiny_run):
    """From `make run` on, each command exits 0 in the environment the ones before it left: `make run` finds
    the run complete, the dry runs list their jobs (the SLURM profile's after the step that installs its
    executor), `make report` writes the page, and after a killed run the rerun is refused until `--unlock`,
    then finishes. `make test` is this suite: its command is checked."""
    commands = [command for command, _ in readme_run]
    assert {"make run", "make -n test", ".venv/bin/snakemake --unlock", "make report"} <= set(commands)
    assert any("--profile profiles/slurm" in command for command in commands)
    failed = []  # every failing command, not only the first: each may lack its own install step
    for command, proc in readme_run:
        out = proc.stdout + proc.stderr
        if command == "rerun before --unlock":
            assert proc.returncode != 0 and "lock" in out.lower(), out[-3000:]
        elif proc.returncode != 0:
            failed.append(f"{command} failed ({proc.returncode}):\n{out[-2500:]}")
        elif command == "make run":
            assert "Nothing to be done" in out
        elif command == "make -n test":
            assert ".venv/bin/python -m pytest" in proc.stdout
    assert not failed, "\n\n".join(failed)
    assert (tiny_run / "reports/report.html").is_file() and (tiny_run / "reports/summary.md").is_file()


def test_make_reports_page_opens_on_the_summary(readme_run, tiny_run, tmp_path):
    """The page `make report` wrote, in a headless browser as the report's screenshot test opens it: it
    draws, and its description starts with the summary, listed first of the categories."""
    assert dict(readme_run)["make report"].returncode == 0
    dom = open_in_browser(tiny_run / "reports/report.html", tmp_path / "report.png")
    if dom is None:
        pytest.skip("no headless browser (Debian package chromium; .ci/run installs it)")
    image = cv2.imread(str(tmp_path / "report.png"))
    assert image is not None and image.shape[:2] == (900, 1280) and image.std() > 10  # it drew something
    shown = re.sub(r"<[^>]+>", "\n", re.sub(r"<(script|style)\b.*?</\1>", "", dom, flags=re.S))
    lines = [line.strip() for line in shown.splitlines() if line.strip()]
    categories = lines[lines.index("Results") + 1:]
    assert categories[0] == "0 summary", lines
    description = next(line for line in categories if len(line) > 40)  # after the category names
    assert description.startswith("Start with the run's results at a glance"), lines
