"""Writes docs/results/default_run.md: the summary (pingpong.reports.summary) of a finished default run.

Run from the repository root on a clean clone's finished `make run` when a change moves the default run's
results: `.venv/bin/python analysis/default_run_summary.py RUN_ROOT COMMIT` (the committed file: the run
of 7ef83a4 in /tmp/dflt). The README's results block must then be the new file's content
(tests/test_readme.py).
"""

import sys
from pathlib import Path

import yaml

from pingpong.reports.summary import run_tables, summary_markdown

OUT = Path(__file__).resolve().parents[1] / "docs/results/default_run.md"


def main(run: Path, commit: str) -> None:
    seed = yaml.safe_load((run / "config/config.yaml").read_text())["seed"]  # as the rule's params.seed
    OUT.write_text(summary_markdown(**run_tables(run), commit=commit, seed=seed))


if __name__ == "__main__":
    main(Path(sys.argv[1]), sys.argv[2])
