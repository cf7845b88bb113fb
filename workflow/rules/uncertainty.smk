# Uncertainty: every estimator fitted and applied to the calibration and test hits (the ensemble is the
# final model's seeds, learning.smk), and the report.
from pingpong.uncertainty.names import ESTIMATORS, MODEL_FILES  # the registry's names

UNCERTAINTY = config["uncertainty"]


rule fit_uncertainty:
    input:
        dataset="processed/dataset.parquet",
        predictions="processed/predictions.parquet",
        members=final_models("final"),
    output:
        tables=expand("processed/uncertainty/{estimator}.parquet", estimator=ESTIMATORS),
        fitted="processed/uncertainty/estimators.json",
        # the learned estimators' models (safetensors) and their sidecars (hyperparameters, provenance)
        models=expand("processed/uncertainty/{model}.safetensors", model=MODEL_FILES),
        sidecars=expand("processed/uncertainty/{model}.json", model=MODEL_FILES),
    params:
        settings=UNCERTAINTY,
        seed=config["seed"],
        code=code("fit_uncertainty"),
    log:
        "logs/fit_uncertainty.log",
    benchmark:
        "benchmarks/results/fit_uncertainty.tsv"
    # before the robot's other runs: the confidence-scaled run waits for it, and ran alone at the end of the
    # default run of da55392 (20 s) when the scheduler started it after them
    priority: 1
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


# On the twin the estimators are also measured against its strike oracle (truth, read by reports only).
rule report_uncertainty:
    input:
        tables=expand("processed/uncertainty/{estimator}.parquet", estimator=ESTIMATORS),
        fitted="processed/uncertainty/estimators.json",
        dataset="processed/dataset.parquet",
        predictions="processed/predictions.parquet",
        oracle=expand("raw/twin_truth/{session}/strike_oracle.parquet", session=sessions()) if TWIN_ONLY else [],
    output:
        md="reports/tables/uncertainty.md",
        csv="reports/tables/uncertainty.csv",
        path_md="reports/tables/uncertainty_path_band.md",
        path_csv="reports/tables/uncertainty_path_band.csv",
        frames_md="reports/tables/uncertainty_by_frame.md",
        frames_csv="reports/tables/uncertainty_by_frame.csv",
        verdict_md="reports/tables/uncertainty_verdict.md",
        verdict_csv="reports/tables/uncertainty_verdict.csv",
        scatter=report(
            "reports/figures/uncertainty_error_vs_uncertainty.png",
            caption="../report/uncertainty_scatter.rst",
            category="uncertainty",
        ),
        error_vs_frames=report(
            "reports/figures/uncertainty_error_vs_frames.png",
            caption="../report/uncertainty_frames.rst",
            category="uncertainty",
        ),
        sparsification=report(
            "reports/figures/uncertainty_sparsification.png",
            caption="../report/uncertainty_sparsification.rst",
            category="uncertainty",
        ),
        spearman_by_frame=report(
            "reports/figures/uncertainty_spearman_by_frame.png",
            caption="../report/uncertainty_spearman_by_frame.rst",
            category="uncertainty",
        ),
        spearman_oracle_by_frame=report(
            "reports/figures/uncertainty_spearman_oracle_by_frame.png",
            caption="../report/uncertainty_spearman_oracle_by_frame.rst",
            category="uncertainty",
        ),
        coverage_by_width=report(
            "reports/figures/uncertainty_coverage_by_width.png",
            caption="../report/uncertainty_coverage_by_width.rst",
            category="uncertainty",
        ),
    params:
        coverage=UNCERTAINTY["coverage"],
        sessions=sessions() if TWIN_ONLY else [],
        seed=config["seed"],
        code=code("report_uncertainty"),
    log:
        "logs/report_uncertainty.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


# Twin only: the final model's error against the twin's strike oracle, and the oracle's causes.
rule report_uncertainty_oracle:
    input:
        dataset="processed/dataset.parquet",
        predictions="processed/predictions.parquet",
        shots=expand("raw/twin_truth/{session}/shots.parquet", session=sessions()),
        oracle=expand("raw/twin_truth/{session}/strike_oracle.parquet", session=sessions()),
    output:
        md="reports/tables/uncertainty_oracle.md",
        csv="reports/tables/uncertainty_oracle.csv",
        figure=report(
            "reports/figures/uncertainty_oracle_std.png",
            caption="../report/uncertainty_oracle_std.rst",
            category="uncertainty",
        ),
    params:
        sessions=sessions(),
        code=code("report_uncertainty_oracle"),
    log:
        "logs/report_uncertainty_oracle.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule report_oracle_learnability:
    input:
        dataset="processed/dataset.parquet",
        predictions="processed/predictions.parquet",
        oracle=expand("raw/twin_truth/{session}/strike_oracle.parquet", session=sessions()),
        verdict="reports/tables/uncertainty_verdict.csv",
    output:
        md="reports/tables/uncertainty_learnability.md",
        csv="reports/tables/uncertainty_learnability.csv",
    params:
        sessions=sessions(),
        seed=config["seed"],
        coverage=config["uncertainty"]["coverage"],
        code=code("report_oracle_learnability"),
    log:
        "logs/report_oracle_learnability.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT
