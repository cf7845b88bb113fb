"""Writes docs/results/paper_scale.md and .csv: a finished paper-scale run (issue 38; `make paper-scale`),
from its report tables and its timing parts:

    .venv/bin/python analysis/paper_scale_summary.py RUN_ROOT COMMIT [OUT_STEM]

RUN_ROOT: the clone the run was made in (its reports/tables/, processed/predictions.parquet and
paper_scale_times.jsonl, the parts analysis/timed_run.py appended). The run's summary (the rows of the
README's results block: hits, Table 1, the robot, the regimes, the uncertainty verdict, each with its 95 %
interval) is followed by what the scale costs and by the tables two things are compared in: Tables 2-4 by
region, the regime map, the learnability ceiling and, where the run has one, the grid slice.
"""

import json
import sys
from pathlib import Path

import pandas as pd
import yaml

from pingpong.reports.summary import run_tables, summary_markdown

OUT = Path(__file__).resolve().parents[1] / "docs/results/paper_scale"
DATA_FOLDERS = ("raw", "interim", "processed", "reports")
CONFIGS = ("config/config.yaml", "config/paper_hits.yaml")  # the Makefile's PAPER_SCALE_CONFIGS
SECTIONS = (  # (table, title, columns shown; None: all)
    ("robot", "Tables 2-4: hits by controller and region (test hits; gain over servoing with a paired "
     "bootstrap interval, McNemar p)", ["controller", "region", "total", "hits", "hit_pct",
                                        "end_distance_mean_cm", "hits_minus_servo", "diff_ci95_low",
                                        "diff_ci95_high", "mcnemar_p", "paper_hit_pct"]),
    ("robot_regimes", "The regime map: balls anticipation and uncertainty win, with paired intervals",
     ["cell", "n_test", "hits_servo", "hits_anticipatory", "hits_uncertainty_aware", "hits_confidence_scaled",
      "hits_perfect", "anticipation_value", "anticipation_ci95_low", "anticipation_ci95_high",
      "uncertainty_value", "uncertainty_ci95_low", "uncertainty_ci95_high"]),
    ("uncertainty_learnability", "Uncertainty at this scale: the learnability ceiling and each estimator's "
     "share of it", None),
    ("grid_slice", "The grid slice: the winner beside the paper's net and the default net", None),
)


def disk_bytes(root: Path) -> int:
    """Bytes of the run's artifacts (the data folders; not the virtual environment)."""
    return sum(p.stat().st_size for folder in DATA_FOLDERS for p in (root / folder).rglob("*") if p.is_file())


def cost_rows(root: Path) -> list[tuple[str, str]]:
    """What the run took: wall and CPU time summed over its parts, peak memory, disk, jobs."""
    times = root / "paper_scale_times.jsonl"
    parts = [json.loads(line) for line in times.read_text().splitlines()] if times.is_file() else []
    rows = [("configuration", " ".join(CONFIGS))]
    if parts:  # parts killed with their session are timed to their last checkpoint (timed_run.py)
        timed = [p for p in parts if p.get("user_s") is not None]
        wall, cpu = sum(p["wall_s"] for p in parts), sum(p["user_s"] + p["system_s"] for p in timed)
        stopped = sum(not p.get("complete", True) for p in parts)
        rss = [p["max_rss_mb"] for p in parts if p.get("max_rss_mb")]
        rows += [("wall time", f"{wall / 3600:.2f} h in {len(parts)} part(s), from {parts[0]['started']}"
                  + (f"; {stopped} stopped before its end, timed to its last record" if stopped else "")),
                 ("parts by commit", "; ".join(
                     f"{p.get('commit') or 'commit not recorded'}: {p['wall_s'] / 3600:.2f} h from "
                     f"{p['started']}" for p in parts)),
                 ("CPU time (user + system)", f"{cpu / 3600:.2f} h"
                  + ("" if len(timed) == len(parts) else f" over the {len(timed)} part(s) that recorded it")),
                 ("peak memory of one job", f"{max(rss) / 1024:.2f} GB" if rss else "not recorded")]
    else:
        rows.append(("wall and CPU time", "not recorded (no paper_scale_times.jsonl)"))
    rows.append(("disk (raw, interim, processed, reports)", f"{disk_bytes(root) / 1e9:.1f} GB"))
    return rows


def section(tables: Path, name: str, title: str, columns) -> str:
    path = tables / f"{name}.csv"
    if not path.is_file():
        return ""
    table = pd.read_csv(path)
    table = table[[c for c in columns if c in table.columns]] if columns else table
    shown = table.to_markdown(index=False, floatfmt=".3g")
    return f"\n## {title}\n\n`reports/tables/{name}.csv`\n\n{shown}\n"


def summary_rows(markdown: str) -> list[tuple[str, str, str]]:
    """(quantity, this run, the paper) of each row of summary_markdown's table."""
    cells = [[c.strip() for c in line.strip("|").split("|")] for line in markdown.splitlines()
             if line.startswith("| ") and not line.startswith("| |")]
    return [tuple(c) for c in cells if len(c) == 3]


def main(root: Path, commit: str, out: Path = OUT) -> None:
    seed = yaml.safe_load((root / "config/config.yaml").read_text())["seed"]
    costs = cost_rows(root)
    summary = summary_markdown(**run_tables(root), commit=commit, seed=seed)
    text = ["# The paper's scale, end to end", "",
            f"The run of commit {commit} at the paper's number of hits, made by `make paper-scale` "
            "(the README's scale section); written by `analysis/paper_scale_summary.py`.", "",
            "| what it took | |", "|---|---|", *[f"| {a} | {b} |" for a, b in costs], "", summary]
    text += [section(root / "reports/tables", *s) for s in SECTIONS]
    out.with_suffix(".md").write_text("\n".join(text))
    rows = [(a, b, "") for a, b in costs] + summary_rows(summary)
    pd.DataFrame(rows, columns=["quantity", "this_run", "paper"]).to_csv(out.with_suffix(".csv"), index=False)


if __name__ == "__main__":
    main(Path(sys.argv[1]), sys.argv[2], *(Path(a) for a in sys.argv[3:4]))
