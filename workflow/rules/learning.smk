# Learning: 5-fold cross-validated grid search (one job per configuration and fold), the refit of the
# winner with several seeds, a ball-only baseline, per-frame predictions and the paper's Table 1.
TRAINING = config["training"]
TRAIN_SETTINGS = {k: TRAINING[k] for k in ("batch_size", "max_epochs", "patience", "min_delta",
                                           "early_frame_weight", "reflect_augment")}
TRAIN_SETTINGS["device"] = config["device"]
GRID = {c["config_id"]: c for c in grid_configurations(TRAINING["grid"], TRAINING["grid_sample"],
                                                      TRAINING["grid_extra"], rng_for(config["seed"], "grid"))}
# report_grid_slice's table, in rule all where training.grid_extra names nets to compare with the winner
GRID_SLICE = ["reports/tables/grid_slice.md"] if TRAINING["grid_extra"] else []
FOLDS = range(TRAINING["n_folds"])


rule train_cv:
    input:
        dataset="processed/dataset.parquet",
    output:
        model="processed/models/cv/{config_id}/fold{fold}.safetensors",
        sidecar="processed/models/cv/{config_id}/fold{fold}.json",
        result="processed/models/cv/{config_id}/fold{fold}_result.json",
    params:
        config=lambda wc: GRID[wc.config_id],
        fold=lambda wc: int(wc.fold),
        settings=TRAIN_SETTINGS,
        seed=config["seed"],
        code=code("train_cv"),
    log:
        "logs/train_cv/{config_id}_fold{fold}.log",
    benchmark:
        "benchmarks/results/train_cv/{config_id}_fold{fold}.tsv"
    resources:
        gpu=1 if config["device"] == "cuda" else 0,
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule select_model:
    input:
        results=expand("processed/models/cv/{config_id}/fold{fold}_result.json", config_id=GRID, fold=FOLDS),
    output:
        selection="processed/models/selection.json",
        md="reports/tables/cv_results.md",
        csv="reports/tables/cv_results.csv",
    params:
        configs=list(GRID.values()),
        code=code("select_model"),
    log:
        "logs/select_model.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


# The final models: the selected configuration refit on the whole training part with seeds seed + k,
# k < training.seeds, each model the mean of its seeds (a deep ensemble's point prediction); `final` is
# the model the reports and the robot use, and its seeds are the uncertainty stage's ensemble.
# ball_only: the same model fed the ball alone; final_{OTHER_INPUTS}: the selected configuration refit on
# the other kind of inputs (curation.smk), so Table 1 and the robot ablation compare causal and
# zero-phase inputs on the same hits, each a mean of as many seeds.
OTHER_FINAL = f"final_{OTHER_INPUTS}"


rule train_final:
    input:
        dataset=lambda wc: f"processed/dataset_{OTHER_INPUTS}.parquet" if wc.variant == OTHER_FINAL
        else "processed/dataset.parquet",
        selection="processed/models/selection.json",
    output:
        model="processed/models/{variant}/seed{seed}.safetensors",
        sidecar="processed/models/{variant}/seed{seed}.json",
    params:
        ball_only=lambda wc: wc.variant == "ball_only",
        settings=TRAIN_SETTINGS,
        seed=lambda wc: config["seed"] + int(wc.seed),
        code=code("train_final"),
    wildcard_constraints:
        variant=f"final|ball_only|{OTHER_FINAL}",
        seed=r"\d+",
    resources:
        gpu=1 if config["device"] == "cuda" else 0,
    log:
        "logs/train_final/{variant}_seed{seed}.log",
    benchmark:
        "benchmarks/results/train_final/{variant}_seed{seed}.tsv"
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule predict:
    input:
        dataset="processed/dataset.parquet",
        other_dataset=f"processed/dataset_{OTHER_INPUTS}.parquet",
        selection="processed/models/selection.json",
        final=final_models("final"),
        ball_only=final_models("ball_only"),
        other_final=final_models(OTHER_FINAL),
        cv_models=expand("processed/models/cv/{config_id}/fold{fold}.safetensors", config_id=GRID, fold=FOLDS),
    output:
        predictions="processed/predictions.parquet",
    params:
        other_final=OTHER_FINAL,
        code=code("predict"),
    log:
        "logs/predict.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule report_strike_error:
    input:
        predictions="processed/predictions.parquet",
    output:
        md="reports/tables/strike_error.md",
        csv="reports/tables/strike_error.csv",
        frames_md="reports/tables/strike_error_by_frame.md",
        frames_csv="reports/tables/strike_error_by_frame.csv",
        figure=report("reports/figures/strike_error.png", caption="../report/strike_error.rst", category="learning"),
    params:
        seeds=TRAINING["seeds"],
        code=code("report_strike_error"),
    log:
        "logs/report_strike_error.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule report_grid_slice:
    input:
        dataset="processed/dataset.parquet",
        selection="processed/models/selection.json",
        results=expand("processed/models/cv/{config_id}/fold{fold}_result.json", config_id=GRID, fold=FOLDS),
        cv_models=expand("processed/models/cv/{config_id}/fold{fold}.safetensors", config_id=GRID, fold=FOLDS),
    output:
        md="reports/tables/grid_slice.md",
        csv="reports/tables/grid_slice.csv",
    params:
        extra=TRAINING["grid_extra"],
        sample=TRAINING["grid_sample"],
        seed=config["seed"],
        code=code("report_grid_slice"),
    log:
        "logs/report_grid_slice.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT
