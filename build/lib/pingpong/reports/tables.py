"""Report tables: one Markdown file for people and one CSV for programs, written atomically."""

import pandas as pd

from pingpong.common.atomic import write_text_atomic


def write_report_table(df: pd.DataFrame, md_path, csv_path, title: str, caption: str) -> None:
    """`df` as `md_path` (title, caption saying what it shows and how it was made, table) and `csv_path`."""
    text = f"# {title}\n\n{caption.strip()}\n\n{df.to_markdown(index=False, floatfmt='.3g')}\n"
    write_text_atomic(md_path, text)
    write_text_atomic(csv_path, df.to_csv(index=False))


def threshold_row(quantity: str, value: float, unit: str, threshold: float, better: str = "below") -> dict:
    """One row of an accuracy table: a measured quantity beside the threshold it must meet
    ('below': value < threshold; 'at least': value >= threshold)."""
    ok = value < threshold if better == "below" else value >= threshold
    return {"quantity": quantity, "value": value, "unit": unit, "threshold": threshold,
            "must_be": better, "ok": bool(ok)}
