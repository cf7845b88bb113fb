# Shared helpers of the rules: sessions, cameras and each stage's code hash.
import re
from pathlib import Path

from pingpong.common.codehash import stage_code_hash
from pingpong.common.stages import STAGE_SCRIPT as _SCRIPT
from pingpong.common.raw_ownership import RawOwnershipError, check as check_raw_ownership
from pingpong.io.lab_layout import CAMERA_SUFFIXES, lab_layout_problems
from pingpong.common.seeding import rng_for
from pingpong.learning.grid import grid_configurations

STAGE_SCRIPT = f"../../{_SCRIPT}"  # every rule's script, relative to workflow/rules/
CONDA_ENV = "../envs/pingpong.yaml"  # every rule's software, for --sdm conda (make installs it into .venv)


def code(rule):
    """The code hash of a rule: its entry pingpong.stages.<rule> and all it imports (docs/architecture.md).
    Every rule passes code(<its own name>); the Snakefile checks that each does."""
    return stage_code_hash(rule, workflow.basedir)


def final_models(variant):
    """The weights of a final model's seeds (learning.smk: the model predicts as their mean)."""
    return expand("processed/models/{variant}/seed{seed}.safetensors", variant=variant,
                  seed=range(config["training"]["seeds"]))


def sessions():
    if config["source"] == "twin":
        return [f"s{i:02d}" for i in range(config["twin"]["n_sessions"])]
    return config["lab"]["sessions"]


def cameras():
    if config["source"] == "twin":
        return [f"cam{c}" for c in range(config["twin"]["n_cameras"])]
    return config["lab"]["cameras"]


def camera_file(session, cam):
    """A camera's recording: raw/sessions/{session}/{cam}.mcap (the twin's; MCAP or a ROS 2 bag), or a
    video file (several of one camera are an error of check_raw_layout)."""
    if config["source"] == "twin":
        return f"raw/sessions/{session}/{cam}.mcap"
    found = [f"raw/sessions/{session}/{cam}{s}" for s in CAMERA_SUFFIXES
             if Path(f"raw/sessions/{session}/{cam}{s}").exists()]
    return found[0] if found else f"raw/sessions/{session}/{cam}.mcap"


def camera_reading(session, cam):
    """How to read a camera file beyond its format (pingpong.io.camera_streams): a video's per-frame
    times from raw/sessions/{session}/{cam}_timestamps.csv when there is one, else from the container
    from lab.video_start_ns[session] on; the image topic of a bag with several (lab.camera_topics)."""
    if config["source"] == "twin":
        return {"timestamps": None, "start_ns": 0, "topic": None}
    csv = f"raw/sessions/{session}/{cam}_timestamps.csv"
    video = not camera_file(session, cam).endswith(".mcap")
    return {"timestamps": csv if video and Path(csv).exists() else None,
            "start_ns": config["lab"]["video_start_ns"].get(session, 0) if video else 0,
            "topic": config["lab"]["camera_topics"].get(cam)}


def timestamp_files(session, cams):
    """The timestamp CSVs the cameras' videos are read with (inputs, so that their edits rerun)."""
    return [r["timestamps"] for r in (camera_reading(session, c) for c in cams) if r["timestamps"]]


def session_cameras(session):
    """The cameras recorded in a session: lab.session_cameras for one recorded with fewer (check_raw_layout
    makes every camera listed for a session have its recording before any job runs)."""
    if config["source"] == "twin":
        return cameras()
    return config["lab"]["session_cameras"].get(session, cameras())


def one_of(names):
    """A wildcard constraint matching exactly these names (cameras and sessions are named by the lab, so
    `overlay_{session}_{cam}.png` could split `lab_01_cam_01` either way without it)."""
    return "|".join(re.escape(n) for n in names) or "(?!)"


wildcard_constraints:
    session=one_of(sessions()),
    cam=one_of(cameras()),
    config_id=r"[0-9a-f]{12}",
    fold=r"\d+",


TRUTH_TABLES = ["ball", "shots", "events", "people", "paddles", "strike_oracle"]


def raw_outputs():
    """Everything under raw/ that the later stages read (written by the twin or by a lab)."""
    captures = calibration_captures()
    return (
        [f for files in captures.values() for f in ([files] if isinstance(files, str) else files)]
        + [camera_file(s, c) for s in sessions() for c in session_cameras(s)]
        + [f"raw/sessions/{s}/openpose/{c}" for s in sessions() for c in session_cameras(s)]
        + [optitrack_path(s) for s in sessions() if has_optitrack()]
    )


def extrinsics_kind():
    """How the fitted cameras are placed (perception.calibration_extrinsics): table_mat, board or points."""
    method = config["perception"]["calibration_extrinsics"]
    return method["type"] if isinstance(method, dict) else method


def calibration_captures(wildcards=None):
    """The calibration rule's inputs by name (unpack): every camera's intrinsics views and extrinsics shot
    in any image format OpenCV reads (pingpong.io.calibration_files; the twin's as it writes them), or
    the imported calibration with the table shots where the lab has them all; the scene-points file of
    perception.calibration_extrinsics. Missing images stand as their expected names (intrinsics_00.png,
    table.png / extrinsics.png), so that the run stops naming them."""
    from pingpong.io.calibration_files import (BOARD_SHOT, TABLE_SHOT, CaptureLayoutError, extrinsics_shot,
                                               intrinsics_views)

    perception = config["perception"]
    method, kind = perception["calibration_extrinsics"], extrinsics_kind()
    folders = [f"raw/calibration/{cam}" for cam in cameras()]
    stem = BOARD_SHOT if kind == "board" else TABLE_SHOT
    try:
        found = {f: extrinsics_shot(f, TABLE_SHOT if perception["calibration_import"] else stem)
                 for f in folders}
    except CaptureLayoutError as err:
        raise WorkflowError(str(err)) from None
    if perception["calibration_import"]:
        shots = [str(s) for s in found.values()] if all(found.values()) else []
        return {"calibration_import": perception["calibration_import"], "shots": shots}
    if config["source"] == "twin":  # the twin_calibration rule's outputs
        views = [f"{f}/intrinsics_{k:02d}.png" for f in folders
                 for k in range(config["twin"]["calibration_views"])]
    else:
        views = [str(v) for f in folders for v in (intrinsics_views(f) or [f"{f}/intrinsics_00.png"])]
    shots = [] if kind == "points" else [str(found[f] or f"{f}/{stem}.png") for f in folders]
    points = [method["file"]] if kind == "points" and "file" in method else []
    return {"views": views, "shots": shots, "scene_points": points}


def has_optitrack():
    """Whether the sessions have OptiTrack poses (lab.optitrack_format none: a lab without motion capture,
    whose ball and pose stages run, but which has no paddles, so no dataset)."""
    return config["source"] == "twin" or config["lab"]["optitrack_format"] != "none"


def optitrack_path(session):
    """The session's OptiTrack poses: the MCAP stream, or a Motive CSV export (lab.optitrack_format)."""
    csv = config["source"] == "lab" and config["lab"]["optitrack_format"] == "motive_csv"
    return f"raw/sessions/{session}/optitrack.{'csv' if csv else 'mcap'}"


def motive_take_start_ns(session):
    """Camera-clock time of a Motive take's first frame (None for the MCAP stream, which has it)."""
    return config["lab"]["motive_take_start_ns"].get(session) if optitrack_path(session).endswith(".csv") else None


def check_raw_layout():
    """Under source: lab, every problem of raw/ against the config, before any job runs (no rule writes raw/
    there, so anything missing could only fail later, one job at a time); under source: twin, whose rules
    write raw/, any file there that the twin did not write with its present content (common.raw_ownership)."""
    if config["source"] != "lab":
        try:
            check_raw_ownership(Path("."))
        except RawOwnershipError as err:
            raise WorkflowError(str(err)) from None
        return
    lab = config["lab"]
    problems = lab_layout_problems(Path("."), lab["sessions"], lab["cameras"],
                                   Path(optitrack_path("any")).name if has_optitrack() else None,
                                   config["perception"]["calibration_import"], extrinsics_kind(),
                                   lab["session_cameras"])
    from pingpong.io.lab_preflight import lab_preflight  # reads video headers (PyAV): a lab's runs only

    # what the recordings' headers and a sample of their OpenPose files say against the config
    problems += lab_preflight(Path("."), lab, config["perception"])
    if problems:
        raise WorkflowError("the lab's recordings under raw/ do not match the config:\n  - "
                            + "\n  - ".join(problems) + "\n(see the README's 'Bringing your lab's recordings')")


def twin_reports():
    """Reports that compare against the twin's truth: only twin runs have one."""
    if config["source"] != "twin":
        return []
    return ["reports/tables/twin_vs_real.md", "reports/tables/perception_accuracy.md",
            "reports/tables/curation_accuracy.md", "reports/tables/uncertainty_oracle.md",
            "reports/tables/twin_keypoints.md", "reports/tables/uncertainty_learnability.md"]


# Report tables by stage, each shown as a page in the HTML report (workflow/rules/report.smk).
TWIN_ONLY = config["source"] == "twin"  # the twin's truth is what those tables measure against
REPORT_TABLES = {
    "twin": ["twin_vs_real", "twin_keypoints"] if TWIN_ONLY else [],
    "perception": ["sync", *(["perception_accuracy"] if TWIN_ONLY else [])],
    "curation": ["curation", *(["curation_accuracy"] if TWIN_ONLY else [])],
    "learning": ["cv_results", "strike_error", "strike_error_by_frame"],
    "uncertainty": ["uncertainty", "uncertainty_verdict", "uncertainty_by_frame", "uncertainty_path_band",
                    *(["uncertainty_oracle", "uncertainty_learnability"] if TWIN_ONLY else [])],
    "robot": ["robot", "robot_limits", "robot_ablation", "servo_accuracy", "robot_region_bias",
              "robot_regimes", "robot_regime_calibration",
              *(["robot_risk_control"] if config["robot"]["estimator"] else [])],
}


def overlay_figures():
    """The QA overlays of the first perception.overlay_sessions sessions, one per camera."""
    chosen = sessions()[: config["perception"]["overlay_sessions"]]
    return [f"reports/figures/overlay_{s}_{c}.png" for s in chosen for c in session_cameras(s)]


def ball_qa_figures():
    """The ball-detection QA sheets (reports.ball_qa), one per session and camera."""
    return [f"reports/figures/ball_qa_{s}_{c}.jpg" for s in sessions() for c in session_cameras(s)]


def report_pages():
    return [f"reports/pages/{stage}/{table}.html" for stage, tables in REPORT_TABLES.items() for table in tables]


def check_stage_rules(rules, root):
    """Each of the workflow's rules but `all` must run the stage script with the code hash of its own
    entry; one that passed another's hash, or none, would rerun on the wrong edits."""
    for r in rules:
        if r.name == "all":
            continue
        if not (r.script or "").endswith(_SCRIPT.rsplit("/", 1)[1]):
            raise WorkflowError(f"{r.name} (a rule) must run the script {_SCRIPT}, not {r.script}")
        if r.params.get("code") != stage_code_hash(r.name, root):
            raise WorkflowError(f"{r.name} (a rule) must pass code('{r.name}') as params.code, the hash of "
                                f"its entry src/pingpong/stages/{r.name}.py")
