"""The script of every rule: runs `pingpong.stages.<rule>.main` (docs/architecture.md).

From a shell: `python workflow/scripts/stage.py RULE --input name=path --output name=path --params p.json`.
"""

from pingpong.common.script import run_rule

run_rule(globals().get("snakemake"))
