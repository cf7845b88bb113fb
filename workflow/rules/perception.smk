# Perception: raw/ -> calibration, ball detections, 2D poses, paddles, 3D signals (interim/).
PERCEPTION = config["perception"]


rule calibration:
    input:
        captures=expand("raw/calibration/{cam}/table.png", cam=cameras()),
        optitrack=f"raw/sessions/{sessions()[0]}/optitrack.mcap",
    output:
        cameras="interim/calibration/cameras.json",
    params:
        cameras=cameras(),
        folders=expand("raw/calibration/{cam}", cam=cameras()),
        import_path=PERCEPTION["calibration_import"],
        import_units=PERCEPTION["calibration_import_units"],
        strict=PERCEPTION["strict_mcap"],
        code=code("calibration.py"),
    log:
        "logs/calibration.log",
    script:
        "../scripts/calibration.py"


rule paddle:
    input:
        cameras="interim/calibration/cameras.json",
        optitrack="raw/sessions/{session}/optitrack.mcap",
        clock=lambda wc: f"raw/sessions/{wc.session}/{cameras()[0]}.mcap",
    output:
        paddle="interim/paddle/{session}.parquet",
    params:
        bodies=PERCEPTION["paddle_bodies"],
        max_gap_s=PERCEPTION["paddle_max_gap_s"],
        strict=PERCEPTION["strict_mcap"],
        code=code("paddle.py"),
    log:
        "logs/paddle/{session}.log",
    script:
        "../scripts/paddle.py"
