"""Report tables as self-contained HTML pages, for `snakemake --report` (which shows HTML and images
inline, and offers other files only as downloads)."""

import html
import re

import pandas as pd

PAGE_STYLE = ("body{font-family:sans-serif;margin:1.5em;max-width:70em}"
              "table{border-collapse:collapse;font-size:90%}"
              "td,th{border:1px solid #ccc;padding:2px 8px;text-align:right}"
              "th{background:#eee}p{line-height:1.4}")


def table_page(markdown: str, table: pd.DataFrame) -> str:
    """HTML page of a report table: the title and caption of its Markdown file (reports.tables'
    layout: '# title', caption paragraphs, the table) and the table itself from its CSV."""
    lines = markdown.splitlines()
    if not lines or not lines[0].startswith("# "):
        raise ValueError(f"report table Markdown must start with '# title'; got {lines[:1]}")
    title = lines[0][2:].strip()
    caption = "\n".join(line for line in lines[1:] if not line.lstrip().startswith("|")).strip()
    paragraphs = "".join(f"<p>{_bold(html.escape(p.strip()))}</p>"
                         for p in caption.split("\n\n") if p.strip())
    body = table.to_html(index=False, float_format=lambda v: f"{v:.3g}", na_rep="", border=0)
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{PAGE_STYLE}</style></head><body><h1>{html.escape(title)}</h1>{paragraphs}{body}"
            "</body></html>\n")


def _bold(text: str) -> str:
    """Markdown's **bold** (a caption's verdict line) as <strong>."""
    return re.sub(r"\*\*(.+?)\*\*", r"<strong>\1</strong>", text)
