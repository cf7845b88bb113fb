"""The paper-scale run's tools (issue 38): the Makefile's target, its timing parts (analysis/timed_run.py)
and its summary (analysis/paper_scale_summary.py), on the tiny run."""

import importlib.util
import json
import re
import signal
import subprocess
import sys
import time

import pandas as pd
from workflow_util import ROOT


def _script(name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / "analysis" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_timed_run_appends_a_part_per_run_and_passes_the_exit_status_on(tmp_path):
    times = tmp_path / "t.jsonl"
    script = str(ROOT / "analysis/timed_run.py")
    ok = subprocess.run([sys.executable, script, str(times), "--", sys.executable, "-c", "sum(range(10**6))"],
                        cwd=ROOT)
    bad = subprocess.run([sys.executable, script, str(times), "--", sys.executable, "-c", "exit(3)"],
                         cwd=tmp_path)
    assert (ok.returncode, bad.returncode) == (0, 3)
    parts = [json.loads(line) for line in times.read_text().splitlines()]
    assert [p["returncode"] for p in parts] == [0, 3]
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    assert [p["commit"] for p in parts] == [head.stdout.strip() or None, None]  # tmp_path: not a checkout
    assert all(p["wall_s"] >= 0 and p["user_s"] >= 0 and p["max_rss_mb"] > 0 for p in parts)


def _timed_sleeper(times, checkpoint_s: float) -> subprocess.Popen:
    """timed_run.py with a short checkpoint, running a child that sleeps 60 s."""
    script = str(ROOT / "analysis/timed_run.py")
    code = (f"import importlib.util, sys; spec = importlib.util.spec_from_file_location('t', {script!r}); "
            "m = importlib.util.module_from_spec(spec); spec.loader.exec_module(m); "
            f"m.CHECKPOINT_S = {checkpoint_s}; sys.exit(m.main(sys.argv[1:]))")
    return subprocess.Popen([sys.executable, "-c", code, str(times), "--", sys.executable, "-c",
                             "import time; sum(range(10**7)); time.sleep(60)"])


def _wait_for_line(times, timeout_s: float = 30.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not (times.is_file() and times.read_text().strip()):
        assert time.monotonic() < deadline, "no checkpoint written"
        time.sleep(0.1)


def test_a_killed_part_keeps_its_time_to_the_last_checkpoint(tmp_path):
    times = tmp_path / "t.jsonl"
    timer = _timed_sleeper(times, 0.2)
    _wait_for_line(times)
    time.sleep(0.5)
    timer.kill()  # as a session's end does: nothing can catch it
    timer.wait()
    part = json.loads(times.read_text())
    assert part["complete"] is False and 0.2 <= part["wall_s"] < 30 and "returncode" not in part
    subprocess.run(["kill", "-9", str(part["pid"])], check=False)  # the orphaned sleeper
    assert not list(tmp_path.glob("*.tmp"))


def test_a_stopped_part_is_recorded_in_full(tmp_path):
    times = tmp_path / "t.jsonl"
    times.write_text(json.dumps({"started": "earlier", "pid": 1, "wall_s": 5.0}) + "\n")
    timer = _timed_sleeper(times, 0.2)
    _wait_for_line(times)
    while len(times.read_text().splitlines()) < 2:
        time.sleep(0.1)
    timer.send_signal(signal.SIGTERM)  # passed to the command, which ends; then the part is written
    assert timer.wait(timeout=30) == 128 + signal.SIGTERM
    earlier, part = (json.loads(line) for line in times.read_text().splitlines())
    assert earlier["wall_s"] == 5.0
    assert part["complete"] is True and part["returncode"] == -signal.SIGTERM and part["user_s"] > 0


def test_the_summary_sums_the_parts_and_reads_the_run(tiny_run, tmp_path):
    summary = _script("paper_scale_summary")
    makefile = (ROOT / "Makefile").read_text()
    configs = re.search(r"^PAPER_SCALE_CONFIGS := (.*)$", makefile, re.M).group(1).split()
    assert configs == list(summary.CONFIGS)
    root = tmp_path / "run"
    (root / "reports").mkdir(parents=True)
    (root / "reports/a.bin").write_bytes(b"x" * 2_000_000)
    (root / "paper_scale_times.jsonl").write_text("\n".join(json.dumps(
        {"started": "2026-12-05T01:00:00+00:00", "wall_s": w, "user_s": 3000.0, "system_s": 600.0,
         "max_rss_mb": 1024.0 * m, "returncode": 0}) for w, m in ((1800.0, 1), (5400.0, 2))))
    costs = dict(summary.cost_rows(root))
    assert costs["wall time"] == "2.00 h in 2 part(s), from 2026-12-05T01:00:00+00:00"
    assert costs["parts by commit"] == ("commit not recorded: 0.50 h from 2026-12-05T01:00:00+00:00; "
                                        "commit not recorded: 1.50 h from 2026-12-05T01:00:00+00:00")
    assert costs["CPU time (user + system)"] == "2.00 h" and costs["peak memory of one job"] == "2.00 GB"
    with (root / "paper_scale_times.jsonl").open("a") as times:  # a part killed before it recorded its CPU
        times.write("\n" + json.dumps({"started": "2026-12-05T04:00:00+00:00", "wall_s": 3600.0,
                                       "user_s": None, "system_s": None, "max_rss_mb": None,
                                       "complete": False}))
    costs = dict(summary.cost_rows(root))
    assert costs["wall time"].startswith("3.00 h in 3 part(s)") and costs["wall time"].endswith(
        "; 1 stopped before its end, timed to its last record")
    assert costs["CPU time (user + system)"] == "2.00 h over the 2 part(s) that recorded it"
    assert costs["disk (raw, interim, processed, reports)"] == "0.0 GB"  # 2 MB
    summary.main(tiny_run, "abc1234", tmp_path / "out")
    text = (tmp_path / "out.md").read_text()
    assert "The run of commit abc1234" in text and "not recorded" in text and "## Tables 2-4" in text
    rows = pd.read_csv(tmp_path / "out.csv").set_index("quantity")
    assert "hits kept" in rows.index
    assert rows.loc["Table 1: strike error 10 frames before the hit", "paper"] == "26.27 cm"
