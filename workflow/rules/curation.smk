# From 3D signals to a curated dataset of hits: filtering, events, segments, curation, dataset, splits.
CURATION = config["curation"]
# the model inputs' kind (curation.inputs) and the other kind, built beside it for comparison
INPUTS = CURATION["inputs"]
OTHER_INPUTS = {"causal": "zero_phase", "zero_phase": "causal"}[INPUTS]


rule filtering:
    input:
        ball3d="interim/ball3d/{session}.parquet",
        pose3d="interim/pose3d/{session}.parquet",
        paddle="interim/paddle/{session}.parquet",
    output:
        ball="interim/filtered/{session}_ball.parquet",
        pose="interim/filtered/{session}_pose.parquet",
        events="interim/events/{session}.parquet",
        # the cleaned, unfiltered measurements of the causal inputs (past-only checks)
        causal_ball="interim/causal/{session}_ball.parquet",
        causal_pose="interim/causal/{session}_pose.parquet",
    params:
        cutoff_ball_hz=CURATION["cutoff_ball_hz"],
        cutoff_pose_hz=CURATION["cutoff_pose_hz"],
        code=code("filtering"),
    log:
        "logs/filtering/{session}.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule segments:
    input:
        ball="interim/filtered/{session}_ball.parquet",
        pose="interim/filtered/{session}_pose.parquet",
        events="interim/events/{session}.parquet",
        paddle="interim/paddle/{session}.parquet",
    output:
        segments="interim/segments/{session}.parquet",
    params:
        session="{session}",
        rules=CURATION["rules"],
        code=code("segments"),
    log:
        "logs/segments/{session}.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule dataset:
    input:
        segments=expand("interim/segments/{session}.parquet", session=sessions()),
        ball=expand("interim/filtered/{session}_ball.parquet", session=sessions()),
        pose=expand("interim/filtered/{session}_pose.parquet", session=sessions()),
        causal_ball=expand("interim/causal/{session}_ball.parquet", session=sessions()),
        causal_pose=expand("interim/causal/{session}_pose.parquet", session=sessions()),
        paddle=expand("interim/paddle/{session}.parquet", session=sessions()),
    output:
        segments="processed/segments.parquet",
        dataset="processed/dataset.parquet",
        # the same hits, splits and labels with the other kind of inputs
        other_inputs=f"processed/dataset_{OTHER_INPUTS}.parquet",
        md="reports/tables/curation.md",
        csv="reports/tables/curation.csv",
    params:
        sessions=sessions(),
        seed=config["seed"],
        n_frames=CURATION["n_frames"],
        test_fraction=CURATION["test_fraction"],
        calibration_fraction=CURATION["calibration_fraction"],
        n_folds=config["training"]["n_folds"],
        inputs=INPUTS,
        other_inputs=OTHER_INPUTS,
        causal_cutoff_pose_hz=CURATION["causal_cutoff_pose_hz"],
        causal_cutoff_ball_hz=CURATION["causal_cutoff_ball_hz"],
        code=code("dataset"),
    log:
        "logs/dataset.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule report_curation:
    input:
        detected=expand("interim/events/{session}.parquet", session=sessions()),
        events=expand("raw/twin_truth/{session}/events.parquet", session=sessions()),
        shots=expand("raw/twin_truth/{session}/shots.parquet", session=sessions()),
        ball=expand("raw/twin_truth/{session}/ball.parquet", session=sessions()),
        ball3d=expand("interim/ball3d/{session}.parquet", session=sessions()),
        filtered=expand("interim/filtered/{session}_ball.parquet", session=sessions()),
        segments="processed/segments.parquet",
    output:
        md="reports/tables/curation_accuracy.md",
        csv="reports/tables/curation_accuracy.csv",
    params:
        sessions=sessions(),
        code=code("report_curation"),
    log:
        "logs/report_curation.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT
