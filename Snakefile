# The anticipatory ping-pong pipeline. Read README.md first; DESIGN.md is the contract.
import os
import sys
from pathlib import Path

from snakemake.utils import min_version

min_version("9.0")

SRC = str(Path(workflow.basedir) / "src")
sys.path.insert(0, SRC)
# Jobs import the package from this checkout, whatever is installed.
os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [SRC, os.environ.get("PYTHONPATH")]))

from pingpong.common.config import validate_config


configfile: "config/config.yaml"


validate_config(config, Path(workflow.basedir) / "config/schema.yaml")


include: "workflow/rules/common.smk"
include: "workflow/rules/twin.smk"


rule all:
    input:
        twin_outputs(),
    default_target: True
