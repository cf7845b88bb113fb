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
