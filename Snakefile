# The anticipatory ping-pong pipeline. Read README.md first; docs/architecture.md is the map and the contract.
import sys
from pathlib import Path

from snakemake.utils import min_version

min_version("9.0")

# The workflow's own imports come from this checkout; jobs import the installed package
# (`pip install -e .` of this checkout, which `make` does) and check at start that it is this one.
sys.path.insert(0, str(Path(workflow.basedir) / "src"))

from pingpong.common.config import check_config_files, validate_config
from pingpong.io.openpose_json import KEYPOINT_MODELS
from pingpong.uncertainty.names import ESTIMATORS

# Snakemake's YAML loader keeps the last of a repeated key and expands aliases without bound: every config
# file of this run (the --configfile ones, read before this line, and the default) is read again strictly.
# Its errors, and the schema's below, name the file that set the key.
CONFIG_SOURCES = check_config_files(
    (["config/config.yaml"] if Path("config/config.yaml").exists() else []) + list(workflow.configfiles)
)


configfile: "config/config.yaml"


# keys whose values are registered names take their enums from the registries
REGISTERED = {"robot.estimator": [*ESTIMATORS, None], "lab.openpose_model": list(KEYPOINT_MODELS)}
validate_config(
    config, Path(workflow.basedir) / "config/schema.yaml", enums=REGISTERED, sources=CONFIG_SOURCES
)


include: "workflow/rules/common.smk"


# The twin's rules write raw/; a lab's raw/ is only ever read, so under source: lab they do not exist and
# whatever is missing there is an error before any job runs, never something to simulate.
check_raw_layout()
if config["source"] == "twin":

    include: "workflow/rules/twin.smk"


include: "workflow/rules/perception.smk"
include: "workflow/rules/curation.smk"
include: "workflow/rules/learning.smk"
include: "workflow/rules/uncertainty.smk"
include: "workflow/rules/robot.smk"
include: "workflow/rules/report.smk"


check_stage_rules(workflow.rules, workflow.basedir)


report: "workflow/report/workflow.rst"


rule all:
    input:
        raw_outputs(),
        "interim/calibration/cameras.json",
        expand("interim/paddle/{session}.parquet", session=sessions() if has_optitrack() else []),
        "reports/tables/curation.md",
        "reports/tables/cv_results.md",
        GRID_SLICE,
        "reports/tables/strike_error.md",
        "reports/tables/uncertainty.md",
        "reports/tables/robot.md",
        "reports/summary.md",
        rules.robot_scene.output,
        twin_reports(),
        overlay_figures(),
        ball_qa_figures(),
        report_pages(),
    default_target: True
