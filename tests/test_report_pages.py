"""Report tables as HTML pages: title, caption paragraphs and the table, escaped."""

import pandas as pd
import pytest

from pingpong.reports.pages import table_page


def test_page_holds_title_caption_and_every_cell():
    markdown = ("# Strike error\n\nMedian error <cm> by region.\n\n**Verdict: *none*.** Second paragraph.\n\n"
                "| a | b |\n|--|--|\n| 1 | 2 |\n")
    page = table_page(markdown, pd.DataFrame({"region": ["left", "all"], "error_cm": [12.345, 7.0]}))
    assert "<h1>Strike error</h1>" in page
    assert ("<p>Median error &lt;cm&gt; by region.</p>"
            "<p><strong>Verdict: *none*.</strong> Second paragraph.</p>") in page
    assert "| a |" not in page  # the Markdown table is replaced by the CSV's
    for cell in ("region", "error_cm", "left", "all", "12.3", ">7<"):
        assert cell in page


def test_markdown_without_a_title_is_refused():
    with pytest.raises(ValueError, match="# title"):
        table_page("no title here\n", pd.DataFrame({"a": [1]}))
