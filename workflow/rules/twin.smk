# The digital twin of the lab: writes raw/ as a real lab would, and the truth in raw/twin_truth/.
TWIN = config["twin"]


rule twin_rig:
    output:
        rig="raw/twin_truth/rig.json",
    params:
        seed=config["seed"],
        n_cameras=TWIN["n_cameras"],
        width=TWIN["width"],
        height=TWIN["height"],
        code=code("twin_rig"),
    log:
        "logs/twin_rig.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule twin_simulate:
    output:
        **{t: f"raw/twin_truth/{{session}}/{t}.parquet" for t in TRUTH_TABLES},
    params:
        seed=config["seed"],
        session="{session}",
        session_index=lambda wc: sessions().index(wc.session),
        rallies=TWIN["rallies_per_session"],
        fault_rates=TWIN["fault_rates"],
        optitrack_hz=TWIN["optitrack_hz"],
        bystander_rate=TWIN["bystander_rate"],
        homoscedastic=TWIN["homoscedastic"],
        serve_toss=TWIN["serve_toss"],
        oracle_draws=TWIN["oracle_draws"],
        code=code("twin_simulate"),
    log:
        "logs/twin_simulate/{session}.log",
    benchmark:
        "benchmarks/results/twin_simulate/{session}.tsv"
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT



rule report_twin_flights:
    input:
        balls=expand("raw/twin_truth/{session}/ball.parquet", session=sessions()),
        shots=expand("raw/twin_truth/{session}/shots.parquet", session=sessions()),
        events=expand("raw/twin_truth/{session}/events.parquet", session=sessions()),
        real="data/realdata/mpi_ball_gun",
    output:
        md="reports/tables/twin_vs_real.md",
        csv="reports/tables/twin_vs_real.csv",
    params:
        code=code("report_twin_flights"),
    log:
        "logs/report_twin_flights.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule twin_calibration:
    input:
        rig="raw/twin_truth/rig.json",
    output:
        expand(
            "raw/calibration/{cam}/intrinsics_{k:02d}.png",
            cam=cameras(),
            k=range(TWIN["calibration_views"]),
        ),
        expand("raw/calibration/{cam}/table.png", cam=cameras()),
    params:
        seed=config["seed"],
        folder=lambda wc, output: Path(output[0]).parents[1],
        views=TWIN["calibration_views"],
        code=code("twin_calibration"),
    log:
        "logs/twin_calibration.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule twin_camera:
    input:
        rig="raw/twin_truth/rig.json",
        ball="raw/twin_truth/{session}/ball.parquet",
        people="raw/twin_truth/{session}/people.parquet",
        paddles="raw/twin_truth/{session}/paddles.parquet",
    output:
        mcap="raw/sessions/{session}/{cam}.mcap",
        ball2d="raw/twin_truth/{session}/{cam}_ball2d.parquet",
        # the balls other than the one in play, only when the room puts some in: pingpong.twin.room's
        # Room.balls, not imported (twin.render would load OpenCV at every Snakemake start)
        **(
            {"other_balls": "raw/twin_truth/{session}/{cam}_other_balls2d.parquet"}
            if TWIN["room"]["second_ball"] > 0 or TWIN["room"]["floor_balls"] > 0 or TWIN["room"]["rolling_ball"]
            or TWIN["room"]["table_balls"] > 0
            else {}
        ),
    params:
        seed=config["seed"],
        session="{session}",
        cam="{cam}",
        jpeg_quality=TWIN["jpeg_quality"],
        room=TWIN["room"],
        code=code("twin_camera"),
    log:
        "logs/twin_camera/{session}_{cam}.log",
    benchmark:
        "benchmarks/results/twin_camera/{session}_{cam}.tsv"
    # before any ready detection, pose2d or OpenPose job: Snakemake otherwise starts the job with the largest
    # input first (a camera's MCAP), and the last camera then ran alone at the end of the perception phase
    # (the default run of da55392: 41 s of one job running, the whole run 14 min 43 s in Snakemake)
    priority: 1
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule twin_openpose:
    input:
        rig="raw/twin_truth/rig.json",
        people="raw/twin_truth/{session}/people.parquet",
    output:
        folder=directory("raw/sessions/{session}/openpose/{cam}"),
    params:
        seed=config["seed"],
        session="{session}",
        cam="{cam}",
        keypoint_errors=TWIN["keypoint_errors"],
        code=code("twin_openpose"),
    log:
        "logs/twin_openpose/{session}_{cam}.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule report_twin_keypoints:
    input:
        rig="raw/twin_truth/rig.json",
        people=expand("raw/twin_truth/{session}/people.parquet", session=sessions()),
        openpose=expand("raw/sessions/{session}/openpose/{cam}", session=sessions(), cam=cameras()),
    output:
        md="reports/tables/twin_keypoints.md",
        csv="reports/tables/twin_keypoints.csv",
    params:
        sessions=sessions(),
        cams=cameras(),
        keypoint_errors=TWIN["keypoint_errors"],
        code=code("report_twin_keypoints"),
    log:
        "logs/report_twin_keypoints.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule twin_optitrack:
    input:
        rig="raw/twin_truth/rig.json",
        paddles="raw/twin_truth/{session}/paddles.parquet",
    output:
        mcap="raw/sessions/{session}/optitrack.mcap",
    params:
        seed=config["seed"],
        session="{session}",
        code=code("twin_optitrack"),
    log:
        "logs/twin_optitrack/{session}.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT
