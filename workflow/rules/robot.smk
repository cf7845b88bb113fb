# The simulated robot: every controller (one job each, tuned on the calibration hits where it has a sweep)
# against the test hits' measured flights, the report (Tables 2-4 and the joint limits), and a few episodes
# as Foxglove scenes with the simulation figure.
import re

from pingpong.robot.controllers import CONTROLLERS, controller_names
from pingpong.robot.regimes import map_cells

ROBOT = config["robot"]
# the registered controllers; those that follow an estimator only when one is configured, the one that
# follows the twin's strike oracle (the ceiling of confidence scaling) only on the twin; the scenes show
# the controllers a real robot could run
SCENE_CONTROLLERS = controller_names(with_uncertainty=ROBOT["estimator"] is not None)
ROBOT_CONTROLLERS = controller_names(with_uncertainty=ROBOT["estimator"] is not None, with_oracle=TWIN_ONLY)
if ROBOT["regime"] not in ROBOT["regimes"]:
    raise ValueError(f"config robot.regime '{ROBOT['regime']}' is not one of robot.regimes {sorted(ROBOT['regimes'])}")
# the configured regime (pingpong.robot.regimes); a calibrated one reads its calibration artifact
REGIME = ROBOT["regimes"][ROBOT["regime"]]
REGIME_CALIBRATION = [f"processed/robot/regime_{ROBOT['regime']}.json"] if REGIME.get("calibrated") else []
ROBOT_SETTINGS = {"regime_name": ROBOT["regime"], "regime": REGIME, "seed": config["seed"],
                  **{k: ROBOT[k] for k in ("alpha_grid", "confidence_quantiles", "max_flight_s")}}
# the regimes calibrated by rule calibrate_regime, and the regime map's cells (name -> regime spec)
CALIBRATED_REGIMES = [name for name, spec in ROBOT["regimes"].items() if spec.get("calibrated")]
MAP_CELLS = map_cells(ROBOT["regimes"], ROBOT["regime_map"]["named"], ROBOT["regime_map"]["base"],
                      ROBOT["regime_map"]["axes"])
# the ablation's timing axis: the timings of these regimes
ABLATION_TIMINGS = ("paper", "fine")
if missing := sorted(set(ABLATION_TIMINGS) - set(ROBOT["regimes"])):
    raise ValueError(f"config robot.regimes lacks {missing}: the robot ablation's timing axis")
# the ball as visual servoing sees it: the causal inputs' measurements (flights.py); with zero-phase inputs,
# the filtered ball the hits are judged on
SEEN_BALLS = expand("interim/causal/{session}_ball.parquet", session=sessions()) if INPUTS == "causal" else []


rule simulate_robot:
    input:
        dataset="processed/dataset.parquet",
        predictions="processed/predictions.parquet",
        balls=expand("interim/filtered/{session}_ball.parquet", session=sessions()),
        seen_balls=SEEN_BALLS,
        calibration=REGIME_CALIBRATION,
        servo_ball="processed/robot/servo_ball.json",
        # the robot's description: read from these inputs, so an edit to either reruns the rule
        limits="config/robot/limits.yaml",
        urdf="config/robot/iiwa14_ridgeback.urdf",
        # a controller that follows an estimator reads the configured one's uncertainties; the oracle's
        # controller the oracle's
        uncertainty=lambda wc: (
            [f"processed/uncertainty/{ROBOT['estimator']}.parquet"]
            if CONTROLLERS[wc.controller].uses_uncertainty
            else ["processed/oracle_uncertainty.parquet"] if CONTROLLERS[wc.controller].uses_oracle else []
        ),
    output:
        sim="processed/sim/{controller}.parquet",
        choice="processed/sim/{controller}.json",
    params:
        controller="{controller}",
        sessions=sessions(),
        seen_cutoff_hz=CURATION["causal_cutoff_ball_hz"],
        code=code("simulate_robot"),
        settings=ROBOT_SETTINGS,
    wildcard_constraints:
        controller="|".join(ROBOT_CONTROLLERS),
    log:
        "logs/simulate_robot/{controller}.log",
    benchmark:
        "benchmarks/results/simulate_robot/{controller}.tsv"
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule report_robot:
    input:
        sims=expand("processed/sim/{controller}.parquet", controller=ROBOT_CONTROLLERS),
        choices=expand("processed/sim/{controller}.json", controller=ROBOT_CONTROLLERS),
        # a calibrated regime's fitted base speed and start (its limits table's robot)
        calibration=REGIME_CALIBRATION,
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
        dynamics=REGIME["dynamics"],
        setting=(f"regime {ROBOT['regime']}: dynamics {REGIME['dynamics']}, timing {REGIME['timing']}, "
                 f"sensing {'calibrated' if REGIME.get('calibrated') else REGIME['sensing']}, "
                 f"servo fit {'calibrated' if REGIME.get('calibrated') else REGIME['servo_fit']}, inputs {INPUTS}"),
        code=code("report_robot"),
    log:
        "logs/report_robot.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule robot_scene:
    input:
        dataset="processed/dataset.parquet",
        predictions="processed/predictions.parquet",
        balls=expand("interim/filtered/{session}_ball.parquet", session=sessions()),
        seen_balls=SEEN_BALLS,
        uncertainty=[f"processed/uncertainty/{ROBOT['estimator']}.parquet"] if ROBOT["estimator"] else [],
        calibration=REGIME_CALIBRATION,
        servo_ball="processed/robot/servo_ball.json",
        sims=expand("processed/sim/{controller}.parquet", controller=SCENE_CONTROLLERS),
        choices=expand("processed/sim/{controller}.json", controller=SCENE_CONTROLLERS),
        limits="config/robot/limits.yaml",
        urdf="config/robot/iiwa14_ridgeback.urdf",
    output:
        # {controller}_test{k}: the k-th test hit of the dataset (its session, rally and hit are in the
        # file's metadata record 'episode')
        mcaps=expand("processed/sim/scenes/{controller}_test{k}.mcap", controller=SCENE_CONTROLLERS,
                     k=range(ROBOT["scene_hits"])),
        figure=report("reports/figures/robot_scene.png", caption="../report/robot_scene.rst", category="robot"),
    params:
        controllers=SCENE_CONTROLLERS,
        sessions=sessions(),
        n_hits=ROBOT["scene_hits"],
        seen_cutoff_hz=CURATION["causal_cutoff_ball_hz"],
        settings=ROBOT_SETTINGS,
        code=code("robot_scene"),
    log:
        "logs/robot_scene.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule robot_ablation:
    input:
        dataset="processed/dataset.parquet",
        predictions="processed/predictions.parquet",
        balls=expand("interim/filtered/{session}_ball.parquet", session=sessions()),
        causal_balls=expand("interim/causal/{session}_ball.parquet", session=sessions()),
        real="data/realdata/mpi_ball_gun",
        calibration=REGIME_CALIBRATION,
        servo_ball="processed/robot/servo_ball.json",
        limits="config/robot/limits.yaml",
        urdf="config/robot/iiwa14_ridgeback.urdf",
    output:
        md="reports/tables/robot_ablation.md",
        csv="reports/tables/robot_ablation.csv",
        servo_md="reports/tables/servo_accuracy.md",
        servo_csv="reports/tables/servo_accuracy.csv",
    params:
        sessions=sessions(),
        settings=ROBOT_SETTINGS,
        timings={name: ROBOT["regimes"][name]["timing"] for name in ABLATION_TIMINGS},
        inputs=INPUTS,
        other_inputs=OTHER_INPUTS,
        other_final=OTHER_FINAL,
        seen_cutoff_hz=CURATION["causal_cutoff_ball_hz"],
        code=code("robot_ablation"),
    log:
        "logs/robot_ablation.log",
    benchmark:
        "benchmarks/results/robot_ablation.tsv"
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


# Twin only: the strike oracle as an uncertainty table of the calibration and test hits, for the robot's
# ceiling of confidence scaling (truth: no estimator reads it).
rule oracle_uncertainty:
    input:
        dataset="processed/dataset.parquet",
        predictions="processed/predictions.parquet",
        oracle=expand("raw/twin_truth/{session}/strike_oracle.parquet", session=sessions()),
    output:
        table="processed/oracle_uncertainty.parquet",
    params:
        sessions=sessions(),
        code=code("oracle_uncertainty"),
    log:
        "logs/oracle_uncertainty.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


# The visual servo's ball model: drag and bounce fitted on half the real ball-gun flights, the lift
# published (pingpong.robot.servo_ball); the other half measures its error (servo_accuracy.md).
rule fit_servo_ball:
    input:
        real="data/realdata/mpi_ball_gun",
    output:
        ball="processed/robot/servo_ball.json",
    params:
        code=code("fit_servo_ball"),
    log:
        "logs/fit_servo_ball.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


# A calibrated regime's sensing and servo fit: fitted on the calibration hits so that servo alone reproduces
# the paper's Table 2 (pingpong.robot.calibration); the config says which regimes are calibrated.
rule calibrate_regime:
    input:
        dataset="processed/dataset.parquet",
        balls=expand("interim/filtered/{session}_ball.parquet", session=sessions()),
        seen_balls=SEEN_BALLS,
        servo_ball="processed/robot/servo_ball.json",
        limits="config/robot/limits.yaml",
        urdf="config/robot/iiwa14_ridgeback.urdf",
    output:
        calibration="processed/robot/regime_{regime}.json",
    params:
        regime="{regime}",
        spec=lambda wc: ROBOT["regimes"][wc.regime],
        grid=ROBOT["calibration"],
        seed=config["seed"],
        sessions=sessions(),
        seen_cutoff_hz=CURATION["causal_cutoff_ball_hz"],
        max_flight_s=ROBOT["max_flight_s"],
        code=code("calibrate_regime"),
    wildcard_constraints:
        regime="|".join(map(re.escape, CALIBRATED_REGIMES)) or "(?!)",
    log:
        "logs/calibrate_regime/{regime}.log",
    benchmark:
        "benchmarks/results/calibrate_regime/{regime}.tsv"
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


# The regime map: every controller in each cell (the named regimes, the base regime over the axes' grid),
# tuned on the calibration hits and run on the test hits (pingpong.robot.regime_map).
rule regime_cell:
    input:
        dataset="processed/dataset.parquet",
        predictions="processed/predictions.parquet",
        balls=expand("interim/filtered/{session}_ball.parquet", session=sessions()),
        seen_balls=SEEN_BALLS,
        servo_ball="processed/robot/servo_ball.json",
        uncertainty=[f"processed/uncertainty/{ROBOT['estimator']}.parquet"] if ROBOT["estimator"] else [],
        oracle=["processed/oracle_uncertainty.parquet"] if TWIN_ONLY else [],
        calibration=lambda wc: ([f"processed/robot/regime_{MAP_CELLS[wc.cell]['calibration_of']}.json"]
                                if MAP_CELLS[wc.cell].get("calibrated") else []),
        limits="config/robot/limits.yaml",
        urdf="config/robot/iiwa14_ridgeback.urdf",
    output:
        cell="processed/robot/regime_map/{cell}.json",
    params:
        cell="{cell}",
        spec=lambda wc: MAP_CELLS[wc.cell],
        seed=config["seed"],
        sessions=sessions(),
        seen_cutoff_hz=CURATION["causal_cutoff_ball_hz"],
        max_flight_s=ROBOT["max_flight_s"],
        alpha_grid=ROBOT["alpha_grid"],
        confidence_quantiles=ROBOT["confidence_quantiles"],
        code=code("regime_cell"),
    wildcard_constraints:
        cell="|".join(map(re.escape, MAP_CELLS)),
    log:
        "logs/regime_cell/{cell}.log",
    benchmark:
        "benchmarks/results/regime_cell/{cell}.tsv"
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


rule report_regime_map:
    input:
        cells=expand("processed/robot/regime_map/{cell}.json", cell=MAP_CELLS),
        calibrations=expand("processed/robot/regime_{regime}.json",
                            regime=[n for n in ROBOT["regime_map"]["named"] if n in CALIBRATED_REGIMES]),
    output:
        md="reports/tables/robot_regimes.md",
        csv="reports/tables/robot_regimes.csv",
        calibration_md="reports/tables/robot_regime_calibration.md",
        calibration_csv="reports/tables/robot_regime_calibration.csv",
        map=report("reports/figures/robot_regime_map.png", caption="../report/robot_regime_map.rst", category="robot"),
        surfaces=expand("reports/figures/robot_alpha_surface_{regime}.png", regime=ROBOT["regime_map"]["named"]),
    params:
        cells=list(MAP_CELLS),
        named=ROBOT["regime_map"]["named"],
        axes=ROBOT["regime_map"]["axes"],
        base=ROBOT["regime_map"]["base"],
        seed=config["seed"],
        n_bootstrap=ROBOT["n_bootstrap"],
        code=code("report_regime_map"),
    log:
        "logs/report_regime_map.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


# The paper's left-region effect, measured on the test hits: the signed strike bias of the predictions the
# robot moves on and the end distance with and without anticipation, by region (reports/tables/
# robot_region_bias.md).
rule robot_region_bias:
    input:
        predictions="processed/predictions.parquet",
        servo="processed/sim/servo.parquet",
        anticipatory="processed/sim/anticipatory.parquet",
        calibration=REGIME_CALIBRATION,
        uncertainty=[f"processed/uncertainty/{ROBOT['estimator']}.parquet"] if ROBOT["estimator"] else [],
    output:
        md="reports/tables/robot_region_bias.md",
        csv="reports/tables/robot_region_bias.csv",
    params:
        settings=ROBOT_SETTINGS,
        estimator=ROBOT["estimator"],
        seed=config["seed"],
        n_bootstrap=ROBOT["n_bootstrap"],
        code=code("robot_region_bias"),
    log:
        "logs/robot_region_bias.log",
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT


# Beyond the paper: anticipation with a guarantee. Each calibration and test hit under every gain rule of
# config robot.risk_control; the gain chosen on the calibration hits so that the miss rate exceeds servo's
# by at most epsilon with probability >= 1 - delta, checked on the test hits and on random re-splits.
rule robot_risk_control:
    input:
        dataset="processed/dataset.parquet",
        predictions="processed/predictions.parquet",
        balls=expand("interim/filtered/{session}_ball.parquet", session=sessions()),
        seen_balls=SEEN_BALLS,
        calibration=REGIME_CALIBRATION,
        servo_ball="processed/robot/servo_ball.json",
        uncertainty=[f"processed/uncertainty/{ROBOT['estimator']}.parquet"] if ROBOT["estimator"] else [],
        limits="config/robot/limits.yaml",
        urdf="config/robot/iiwa14_ridgeback.urdf",
    output:
        md="reports/tables/robot_risk_control.md",
        csv="reports/tables/robot_risk_control.csv",
    params:
        sessions=sessions(),
        seen_cutoff_hz=CURATION["causal_cutoff_ball_hz"],
        settings=ROBOT_SETTINGS,
        risk_control=ROBOT["risk_control"],
        estimator=ROBOT["estimator"],
        seed=config["seed"],
        code=code("robot_risk_control"),
    log:
        "logs/robot_risk_control.log",
    benchmark:
        "benchmarks/results/robot_risk_control.tsv"
    conda:
        CONDA_ENV
    script:
        STAGE_SCRIPT

