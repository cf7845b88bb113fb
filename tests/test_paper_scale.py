"""The paper-scale run's tools (issue 38): the Makefile's target, its timing parts (analysis/timed_run.py)
and its summary (analysis/paper_scale_summary.py), on the tiny run."""

import importlib.util
import json
import re
import subprocess
import sys

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
    ok = subprocess.run([sys.executable, script, str(times), "--", sys.executable, "-c", "sum(range(10**6))"])
    bad = subprocess.run([sys.executable, script, str(times), "--", sys.executable, "-c", "exit(3)"])
    assert (ok.returncode, bad.returncode) == (0, 3)
    parts = [json.loads(line) for line in times.read_text().splitlines()]
    assert [p["returncode"] for p in parts] == [0, 3]
    assert all(p["wall_s"] >= 0 and p["user_s"] >= 0 and p["max_rss_mb"] > 0 for p in parts)


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
    assert costs["wall time"].startswith("2.00 h in 2 part(s)")
    assert costs["CPU time (user + system)"] == "2.00 h" and costs["peak memory of one job"] == "2.00 GB"
    assert costs["disk (raw, interim, processed, reports)"] == "0.0 GB"  # 2 MB
    summary.main(tiny_run, "abc1234", tmp_path / "out")
    text = (tmp_path / "out.md").read_text()
    assert "The run of commit abc1234" in text and "not recorded" in text and "## Tables 2-4" in text
    rows = pd.read_csv(tmp_path / "out.csv").set_index("quantity")
    assert "hits kept" in rows.index
    assert rows.loc["Table 1: strike error 10 frames before the hit", "paper"] == "26.27 cm"
