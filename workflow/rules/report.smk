# The HTML report (`snakemake --report reports/report.html`): every report table as a page, by stage,
# beside the figures that the stage rules mark with report().
rule report_page:
    input:
        md="reports/tables/{table}.md",
        csv="reports/tables/{table}.csv",
    output:
        page=report("reports/pages/{stage}/{table}.html", caption="../report/table.rst", category="{stage}"),
    params:
        code=code("report_page"),
    wildcard_constraints:
        stage="|".join(REPORT_TABLES),
        table=r"[a-z_]+",
    log:
        "logs/report_page/{stage}_{table}.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


# The run's results at a glance (the README's results block for the default run; the HTML report's first
# page): kept hits and split, the twin's accuracy checks, Table 1 with intervals, Tables 2-4, the verdict.
rule report_summary:
    input:
        curation="reports/tables/curation.csv",
        predictions="processed/predictions.parquet",
        strike_error="reports/tables/strike_error.csv",
        robot="reports/tables/robot.csv",
        verdict="reports/tables/uncertainty_verdict.csv",
        perception_accuracy=["reports/tables/perception_accuracy.csv"] if TWIN_ONLY else [],
        curation_accuracy=["reports/tables/curation_accuracy.csv"] if TWIN_ONLY else [],
        twin_vs_real=["reports/tables/twin_vs_real.csv"] if TWIN_ONLY else [],
        twin_keypoints=["reports/tables/twin_keypoints.csv"] if TWIN_ONLY else [],
        uncertainty_learnability=["reports/tables/uncertainty_learnability.csv"] if TWIN_ONLY else [],
        robot_regimes="reports/tables/robot_regimes.csv",
        robot_regime_calibration="reports/tables/robot_regime_calibration.csv",
        robot_risk_control=["reports/tables/robot_risk_control.csv"] if ROBOT["estimator"] else [],
    output:
        md=report("reports/summary.md", caption="../report/summary.rst", category="0 summary"),
    params:
        seed=config["seed"],
        code=code("report_summary"),
    log:
        "logs/report_summary.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT
