# Perception: raw/ -> calibration, ball detections, 2D poses, paddles, 3D signals (interim/).
from pingpong.perception.scene import Scene

PERCEPTION = config["perception"]


rule calibration:
    input:
        unpack(calibration_captures),
        optitrack=[optitrack_path(sessions()[0])] if has_optitrack() else [],
    output:
        cameras="interim/calibration/cameras.json",
    params:
        cameras=cameras(),
        folders=expand("raw/calibration/{cam}", cam=cameras()),
        import_units=PERCEPTION["calibration_import_units"],
        import_world=PERCEPTION["calibration_import_world"],
        import_names=PERCEPTION["calibration_import_names"],
        extrinsics=PERCEPTION["calibration_extrinsics"],
        board=PERCEPTION["calibration_board"],
        fit_k3=PERCEPTION["calibration_fit_k3"],
        source=config["source"],
        max_rms_share=PERCEPTION["calibration_max_rms_share"],
        frame_crop=PERCEPTION["frame_crop"],
        strict=PERCEPTION["strict_mcap"],
        take_start_ns=motive_take_start_ns(sessions()[0]) if has_optitrack() else None,
        code=code("calibration"),
    log:
        "logs/calibration.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule paddle:
    input:
        cameras="interim/calibration/cameras.json",
        optitrack=lambda wc: optitrack_path(wc.session),
        clock=lambda wc: camera_file(wc.session, session_cameras(wc.session)[0]),
        timestamps=lambda wc: timestamp_files(wc.session, session_cameras(wc.session)[:1]),
    output:
        paddle="interim/paddle/{session}.parquet",
    params:
        bodies=PERCEPTION["paddle_bodies"],
        max_gap_s=PERCEPTION["paddle_max_gap_s"],
        strict=PERCEPTION["strict_mcap"],
        take_start_ns=lambda wc: motive_take_start_ns(wc.session),
        reading=lambda wc: camera_reading(wc.session, session_cameras(wc.session)[0]),
        code=code("paddle"),
    log:
        "logs/paddle/{session}.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule detection:
    input:
        stream=lambda wc: camera_file(wc.session, wc.cam),
        timestamps=lambda wc: timestamp_files(wc.session, [wc.cam]),
    output:
        detections="interim/detections/{session}/{cam}.parquet",
        candidates="interim/ball_candidates/{session}/{cam}.parquet",
    params:
        reading=lambda wc: camera_reading(wc.session, wc.cam),
        strict=PERCEPTION["strict_mcap"],
        ball=PERCEPTION["ball"],
        code=code("detection"),
    log:
        "logs/detection/{session}_{cam}.log",
    benchmark:
        "benchmarks/results/detection/{session}_{cam}.tsv"
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule pose2d:
    input:
        cameras="interim/calibration/cameras.json",
        stream=lambda wc: camera_file(wc.session, wc.cam),
        timestamps=lambda wc: timestamp_files(wc.session, [wc.cam]),
        openpose="raw/sessions/{session}/openpose/{cam}",
    output:
        pose2d="interim/pose2d/{session}/{cam}.parquet",
    params:
        cam="{cam}",
        min_confidence=PERCEPTION["pose_min_confidence"],
        # the twin writes OpenPose's own BODY_25 files
        model=config["lab"]["openpose_model"] if config["source"] == "lab" else "BODY_25",
        pattern=config["lab"]["openpose_pattern"] if config["source"] == "lab" else "openpose",
        reading=lambda wc: camera_reading(wc.session, wc.cam),
        strict=PERCEPTION["strict_mcap"],
        code=code("pose2d"),
    log:
        "logs/pose2d/{session}_{cam}.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule sync_check:
    input:
        streams=lambda wc: [camera_file(wc.session, c) for c in session_cameras(wc.session)],
        timestamps=lambda wc: timestamp_files(wc.session, session_cameras(wc.session)),
    output:
        sync="interim/sync/{session}.parquet",
    params:
        session="{session}",
        cams=lambda wc: session_cameras(wc.session),
        readings=lambda wc: [camera_reading(wc.session, c) for c in session_cameras(wc.session)],
        strict=PERCEPTION["strict_mcap"],
        code=code("sync_check"),
    log:
        "logs/sync_check/{session}.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule report_sync:
    input:
        syncs=expand("interim/sync/{session}.parquet", session=sessions()),
    output:
        md="reports/tables/sync.md",
        csv="reports/tables/sync.csv",
    params:
        sessions=sessions(),
        code=code("report_sync"),
    log:
        "logs/report_sync.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule triangulation:
    input:
        cameras="interim/calibration/cameras.json",
        sync="interim/sync/{session}.parquet",  # the cameras share a clock (else sync_check stopped)
        detections=lambda wc: expand(
            "interim/detections/{session}/{cam}.parquet", session=wc.session, cam=session_cameras(wc.session)
        ),
        candidates=lambda wc: expand(
            "interim/ball_candidates/{session}/{cam}.parquet", session=wc.session, cam=session_cameras(wc.session)
        ),
        pose2d=lambda wc: expand(
            "interim/pose2d/{session}/{cam}.parquet", session=wc.session, cam=session_cameras(wc.session)
        ),
    output:
        ball3d="interim/ball3d/{session}.parquet",
        # {cam}.parquet per camera of the session (DETECTIONS): its 2D ball after the views' agreement
        ball_views=directory("interim/ball_views/{session}"),
        pose3d="interim/pose3d/{session}.parquet",
    params:
        cams=lambda wc: session_cameras(wc.session),
        max_reproj_share=PERCEPTION["max_reproj_share"],
        min_views=PERCEPTION["min_views"],
        ball_pair_min_frames=PERCEPTION["ball_pair_min_frames"],
        ball_flight=PERCEPTION["ball_flight"],
        scene=PERCEPTION["scene"],
        association_share=PERCEPTION["association_share"],
        pose_gate_noise_factor=PERCEPTION["pose_gate_noise_factor"],
        pose_confidence_weights=PERCEPTION["pose_confidence_weights"],
        pose_view_policy=PERCEPTION["pose_view_policy"],
        pose_max_mean_reproj_px=PERCEPTION["pose_max_mean_reproj_px"],
        code=code("triangulation"),
    log:
        "logs/triangulation/{session}.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule pose_trc:
    input:
        pose3d="interim/pose3d/{session}.parquet",
    output:
        trc="interim/trc/{session}/{slot}.trc",
    wildcard_constraints:
        slot=one_of(Scene.from_config(PERCEPTION["scene"]).slots),
    params:
        slot="{slot}",
        code=code("pose_trc"),
    log:
        "logs/pose_trc/{session}_{slot}.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule report_overlay:
    input:
        cameras="interim/calibration/cameras.json",
        stream=lambda wc: camera_file(wc.session, wc.cam),
        timestamps=lambda wc: timestamp_files(wc.session, [wc.cam]),
        detections="interim/detections/{session}/{cam}.parquet",
        ball3d="interim/ball3d/{session}.parquet",
        pose3d="interim/pose3d/{session}.parquet",
    output:
        figure=report(
            "reports/figures/overlay_{session}_{cam}.png",
            caption="../report/overlay.rst",
            category="perception",
        ),
    params:
        session="{session}",
        cam="{cam}",
        n_frames=PERCEPTION["overlay_frames"],
        reading=lambda wc: camera_reading(wc.session, wc.cam),
        strict=PERCEPTION["strict_mcap"],
        code=code("report_overlay"),
    log:
        "logs/report_overlay/{session}_{cam}.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule report_ball_qa:
    input:
        stream=lambda wc: camera_file(wc.session, wc.cam),
        timestamps=lambda wc: timestamp_files(wc.session, [wc.cam]),
        candidates="interim/ball_candidates/{session}/{cam}.parquet",
        ball_views="interim/ball_views/{session}",  # triangulation's folder: {cam}.parquet is the camera's
    output:
        figure=report(
            "reports/figures/ball_qa_{session}_{cam}.jpg",
            caption="../report/ball_qa.rst",
            category="perception",
        ),
    params:
        session="{session}",
        cam="{cam}",
        reading=lambda wc: camera_reading(wc.session, wc.cam),
        strict=PERCEPTION["strict_mcap"],
        code=code("report_ball_qa"),
    log:
        "logs/report_ball_qa/{session}_{cam}.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule report_perception:
    input:
        cameras="interim/calibration/cameras.json",
        rig="raw/twin_truth/rig.json",
        detections=expand("interim/detections/{session}/{cam}.parquet", session=sessions(), cam=cameras()),
        ball_views=expand("interim/ball_views/{session}", session=sessions()),
        ball2d=expand("raw/twin_truth/{session}/{cam}_ball2d.parquet", session=sessions(), cam=cameras()),
        ball3d=expand("interim/ball3d/{session}.parquet", session=sessions()),
        ball=expand("raw/twin_truth/{session}/ball.parquet", session=sessions()),
        pose3d=expand("interim/pose3d/{session}.parquet", session=sessions()),
        people=expand("raw/twin_truth/{session}/people.parquet", session=sessions()),
        paddle=expand("interim/paddle/{session}.parquet", session=sessions()),
        paddles=expand("raw/twin_truth/{session}/paddles.parquet", session=sessions()),
    output:
        md="reports/tables/perception_accuracy.md",
        csv="reports/tables/perception_accuracy.csv",
    params:
        sessions=sessions(),
        cams=cameras(),
        code=code("report_perception"),
    log:
        "logs/report_perception.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT
