# Shared helpers of the rules: sessions, cameras and each stage's code hash.
from pathlib import Path

from pingpong.common.codehash import code_hash


def code(script):
    """The hash of a stage's script and every pingpong module it imports (see DESIGN.md)."""
    return code_hash(f"workflow/scripts/{script}", workflow.basedir)


def sessions():
    if config["source"] == "twin":
        return [f"s{i:02d}" for i in range(config["twin"]["n_sessions"])]
    return config["lab"]["sessions"]


def cameras():
    if config["source"] == "twin":
        return [f"cam{c}" for c in range(config["twin"]["n_cameras"])]
    return config["lab"]["cameras"]


wildcard_constraints:
    session=r"[A-Za-z0-9_\-]+",
    cam=r"cam\d+",


TRUTH_TABLES = ["ball", "shots", "events", "people", "paddles"]


def raw_outputs():
    """Everything under raw/ that the later stages read (written by the twin or by a lab)."""
    return (
        expand("raw/calibration/{cam}/table.png", cam=cameras())
        + expand("raw/sessions/{session}/{cam}.mcap", session=sessions(), cam=cameras())
        + expand("raw/sessions/{session}/openpose/{cam}", session=sessions(), cam=cameras())
        + expand("raw/sessions/{session}/optitrack.mcap", session=sessions())
    )
