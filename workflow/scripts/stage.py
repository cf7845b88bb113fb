"""The script of every rule: runs `pingpong.stages.<rule>.main` (docs/architecture.md).

From a shell: `python workflow/scripts/stage.py RULE --input name=path --output name=path --params p.json`.
"""

from pingpong.common.numerics import pin_numerics

pin_numerics()  # before numpy, scipy, torch or cv2 loads: their kernels and threads (docs/performance.md)

from pingpong.common.script import run_rule  # noqa: E402  (after the pin)

run_rule(globals().get("snakemake"))
