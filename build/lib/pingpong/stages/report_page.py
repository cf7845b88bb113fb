"""Rule report_page: one report table (Markdown caption + CSV) as an HTML page for the HTML report."""

from pathlib import Path

import pandas as pd

from pingpong.common.atomic import write_text_atomic
from pingpong.reports.pages import table_page


def main(ctx):
    page = table_page(Path(ctx.input.md).read_text(), pd.read_csv(ctx.input.csv))
    write_text_atomic(ctx.output.page, page)
