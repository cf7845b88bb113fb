# The simulated robot: every controller (one job each, tuned on the calibration hits where it has a sweep)
# against the test hits' measured flights, and the report (Tables 2-4 and the joint limits).
from pingpong.uncertainty.tables import ESTIMATORS

ROBOT = config["robot"]
ROBOT_CONTROLLERS = ["servo", "anticipatory", "uncertainty_aware"] + (
    ["confidence_scaled"] if ROBOT["estimator"] else [])
ROBOT_SETTINGS = {k: ROBOT[k] for k in ("anticipation_start_frame", "servo_start_frame", "servo_period_frames",
                                        "latency_frames", "control_dt_s", "alpha_grid", "confidence_quantiles",
                                        "max_flight_s")}
if ROBOT["estimator"] and ROBOT["estimator"] not in ESTIMATORS:
    raise WorkflowError(f"robot.estimator '{ROBOT['estimator']}' is not an uncertainty estimator; "
                        f"expected one of {list(ESTIMATORS)} or null")


rule simulate_robot:
    input:
        dataset="processed/dataset.parquet",
        predictions="processed/predictions.parquet",
        balls=expand("interim/filtered/{session}_ball.parquet", session=sessions()),
        # the robot's description is read at run time, so it is not in the code hash
        limits="config/robot/limits.yaml",
        urdf="config/robot/iiwa14_ridgeback.urdf",
        # the confidence-scaled controller follows the configured estimator's uncertainties
        uncertainty=lambda wc: (
            [f"processed/uncertainty/{ROBOT['estimator']}.parquet"] if wc.controller == "confidence_scaled" else []
        ),
    output:
        sim="processed/sim/{controller}.parquet",
        choice="processed/sim/{controller}.json",
    params:
        controller="{controller}",
        sessions=sessions(),
        code=code("simulate_robot.py"),
        settings=ROBOT_SETTINGS,
    wildcard_constraints:
        controller="|".join(ROBOT_CONTROLLERS),
    log:
        "logs/simulate_robot/{controller}.log",
    benchmark:
        "benchmarks/results/simulate_robot/{controller}.tsv"
    script:
        "../scripts/simulate_robot.py"


rule report_robot:
    input:
        sims=expand("processed/sim/{controller}.parquet", controller=ROBOT_CONTROLLERS),
        choices=expand("processed/sim/{controller}.json", controller=ROBOT_CONTROLLERS),
        limits="config/robot/limits.yaml",
        urdf="config/robot/iiwa14_ridgeback.urdf",
    output:
        md="reports/tables/robot.md",
        csv="reports/tables/robot.csv",
        limits_md="reports/tables/robot_limits.md",
        limits_csv="reports/tables/robot_limits.csv",
    params:
        controllers=ROBOT_CONTROLLERS,
        seed=config["seed"],
        n_bootstrap=ROBOT["n_bootstrap"],
        limit_samples=ROBOT["limit_samples"],
        code=code("report_robot.py"),
    log:
        "logs/report_robot.log",
    script:
        "../scripts/report_robot.py"
