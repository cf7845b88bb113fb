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
        code=code("twin_rig.py"),
    log:
        "logs/twin_rig.log",
    script:
        "../scripts/twin_rig.py"


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
        code=code("twin_simulate.py"),
    log:
        "logs/twin_simulate/{session}.log",
    benchmark:
        "benchmarks/results/twin_simulate/{session}.tsv"
    script:
        "../scripts/twin_simulate.py"



rule report_twin_flights:
    input:
        balls=expand("raw/twin_truth/{session}/ball.parquet", session=sessions()),
        shots=expand("raw/twin_truth/{session}/shots.parquet", session=sessions()),
        real="data/realdata/mpi_ball_gun",
    output:
        md="reports/tables/twin_vs_real.md",
        csv="reports/tables/twin_vs_real.csv",
    params:
        code=code("report_twin_flights.py"),
    log:
        "logs/report_twin_flights.log",
    script:
        "../scripts/report_twin_flights.py"
