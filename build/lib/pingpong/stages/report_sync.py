"""Rule report_sync: every session's camera clocks side by side (reports/tables/sync.md)."""

import pandas as pd

from pingpong.common.artifacts import read_table
from pingpong.perception.schemas import SYNC
from pingpong.reports.tables import write_report_table

CAPTION = """Each camera's clock per session, as the sync_check rule found it before triangulation
(pingpong.perception.sync): frames, rate from the median frame interval, first and last frame time (ns,
camera clock), frames dropped (intervals of 1.5 median intervals or more) and frame times not after the
one before. A session whose cameras disagree (rate, first frame, count or any frame time by more than
half a frame) stops at sync_check with an error naming the camera; drops alone are warnings."""


def main(ctx):
    sessions = zip(ctx.params["sessions"], ctx.input.syncs, strict=True)
    table = pd.concat([read_table(f, SYNC).assign(session=s) for s, f in sessions], ignore_index=True)
    write_report_table(table[["session", *SYNC.columns]], ctx.output.md, ctx.output.csv, "Camera sync",
                       CAPTION)
