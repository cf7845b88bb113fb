"""Rule report_summary: the run's results at a glance (reports/summary.md), from its report tables.

The first thing the HTML report shows, and what the README's results block is for the default run.
"""

import subprocess
from pathlib import Path

import pandas as pd

from pingpong.common.artifacts import read_table
from pingpong.common.atomic import write_text_atomic
from pingpong.learning.schemas import PREDICTIONS
from pingpong.reports.summary import EXTRA_TABLES, summary_markdown

CHECKOUT = Path(__file__).resolve().parents[3]


def checkout_commit(root: Path = CHECKOUT) -> str:
    """The checkout's commit (short), '+ changes' when tracked files differ from it; a copy without git
    history says so rather than guess."""
    def git(*args):
        return subprocess.run(["git", *args], cwd=root, capture_output=True, text=True)

    head = git("rev-parse", "--short", "HEAD")
    if head.returncode != 0:
        return "unknown (not a git checkout)"
    dirty = git("status", "--porcelain", "--untracked-files=no").stdout.strip()
    return head.stdout.strip() + (" + uncommitted changes" if dirty else "")


def main(ctx):
    # the twin's accuracy tables, one path or none (a lab run has no truth to measure against)
    optional = {k: pd.read_csv(ctx.optional_input(k)) for k in ("perception_accuracy", "curation_accuracy")
                if ctx.optional_input(k)}
    extra = {k: pd.read_csv(ctx.optional_input(k)) for k in EXTRA_TABLES if ctx.optional_input(k)}
    text = summary_markdown(pd.read_csv(ctx.input.curation), read_table(ctx.input.predictions, PREDICTIONS),
                            pd.read_csv(ctx.input.strike_error), pd.read_csv(ctx.input.robot),
                            pd.read_csv(ctx.input.verdict), commit=checkout_commit(), seed=ctx.params["seed"],
                            extra=extra, **optional)
    write_text_atomic(ctx.output.md, text)
