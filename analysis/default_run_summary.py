"""Writes docs/results/default_run.md: the summary (pingpong.reports.summary) of a finished default run.

Run from the repository root on a clean clone's finished `make run` when a change moves the default run's
results: `.venv/bin/python analysis/default_run_summary.py RUN_ROOT COMMIT` (the committed file: the run
of 7ef83a4 in /tmp/dflt). The README's results block must then be the new file's content
(tests/test_readme.py).
"""

import sys
from pathlib import Path

import pandas as pd
import yaml

from pingpong.common.artifacts import read_table
from pingpong.learning.schemas import PREDICTIONS
from pingpong.reports.summary import summary_markdown

OUT = Path(__file__).resolve().parents[1] / "docs/results/default_run.md"


def main(run: Path, commit: str) -> None:
    tables = run / "reports/tables"
    seed = yaml.safe_load((run / "config/config.yaml").read_text())["seed"]  # as the rule's params.seed
    text = summary_markdown(
        pd.read_csv(tables / "curation.csv"), read_table(run / "processed/predictions.parquet", PREDICTIONS),
        pd.read_csv(tables / "strike_error.csv"), pd.read_csv(tables / "robot.csv"),
        pd.read_csv(tables / "uncertainty_verdict.csv"), commit=commit, seed=seed,
        perception_accuracy=pd.read_csv(tables / "perception_accuracy.csv"),
        curation_accuracy=pd.read_csv(tables / "curation_accuracy.csv"))
    OUT.write_text(text)


if __name__ == "__main__":
    main(Path(sys.argv[1]), sys.argv[2])
