"""A lab's raw/ is read, never written: under source: lab no twin rule exists, and whatever is missing or
misnamed stops the workflow before any job runs, naming the path and what belongs there."""

import hashlib
import shutil

import pytest
from workflow_util import copy_checkout, snakemake, write_config

from pingpong.io.lab_layout import lab_layout_problems

LAB = {"source": "lab", "lab": {"sessions": ["s00"], "cameras": ["cam0", "cam1", "cam2"]}}


def raw_digest(root) -> dict[str, str]:
    """SHA-256 of every file under raw/ (and the folders, as empty entries)."""
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
            for p in sorted((root / "raw").rglob("*"))}


@pytest.fixture
def lab_root(tiny_run, tmp_path):
    """The tiny run's recordings laid out as a lab hands them over (calibration views, streams, OpenPose,
    OptiTrack), and no twin truth."""
    root = copy_checkout(tmp_path)
    shutil.copytree(tiny_run / "raw/calibration", root / "raw/calibration")
    shutil.copytree(tiny_run / "raw/sessions/s00", root / "raw/sessions/s00")
    write_config(root, LAB)
    return root


def said(proc) -> str:
    """What Snakemake printed: an error while reading the workflow goes to stdout or stderr by the flags."""
    return proc.stdout + proc.stderr


def scheduled_rules(proc) -> set[str]:
    """The rules of a dry run's job table (`snakemake -n` prints 'rule  count' rows after 'job')."""
    lines = proc.stdout.splitlines()
    start = next(i for i, line in enumerate(lines) if line.split()[:2] == ["job", "count"])
    rows = [line.split() for line in lines[start + 2:]]
    return {row[0] for row in rows if len(row) == 2 and row[0] != "total"}


def test_a_complete_lab_layout_schedules_no_twin_rule(lab_root):
    proc = snakemake(lab_root, "-n")
    rules = scheduled_rules(proc)
    assert {"calibration", "detection", "pose2d", "triangulation", "paddle"} <= rules
    assert not {r for r in rules if r.startswith("twin_") or r == "report_twin_flights"}


def test_no_rule_writes_raw_under_source_lab(lab_root):
    """Every job of the whole workflow forced (--forceall), and no output under raw/; a raw/ file asked for
    has no rule to make it."""
    proc = snakemake(lab_root, "-n", "--forceall")
    outputs = [f.strip() for line in proc.stdout.splitlines() if line.strip().startswith("output:")
               for f in line.split(":", 1)[1].split(",")]
    assert len(outputs) > 50 and "interim/pose3d/s00.parquet" in outputs
    assert not [f for f in outputs if f.startswith("raw/")]
    for target in ("raw/twin_truth/rig.json", "raw/sessions/s00/cam9.mcap", "raw/sessions/s00/openpose/cam1"):
        proc = snakemake(lab_root, "-n", target, check=False)
        assert proc.returncode != 0 and "MissingRuleException" in said(proc), target


def test_missing_openpose_and_calibration_view_stop_before_any_job(lab_root):
    shutil.rmtree(lab_root / "raw/sessions/s00/openpose/cam1")
    (lab_root / "raw/calibration/cam2/table.png").unlink()
    before = raw_digest(lab_root)
    for args in (["-n"], []):
        proc = snakemake(lab_root, *args, check=False)
        assert proc.returncode != 0
        assert "raw/sessions/s00/openpose/cam1/: missing or empty; expected the OpenPose-family" in said(proc)
        assert "raw/calibration/cam2/table.*: missing; expected the camera's view of the table" in said(proc)
    assert raw_digest(lab_root) == before
    assert not (lab_root / "interim").exists() or not any((lab_root / "interim").rglob("*.parquet"))
    assert not (lab_root / "logs").exists()  # no job started


def test_cameras_named_as_the_files_do(lab_root):
    """Any camera name works (no `cam\\d+` constraint); a configured camera with no recording anywhere is an
    error listing the names the files have."""
    write_config(lab_root, {**LAB, "lab": {**LAB["lab"], "cameras": ["cam_01", "cam1", "cam2"]}})
    proc = snakemake(lab_root, "-n", check=False)
    assert proc.returncode != 0
    assert "no session has a recording of ['cam_01']" in said(proc)
    assert "named ['cam0', 'cam1', 'cam2']: name the cameras as the files do" in said(proc)
    for old, new in (("cam0", "cam_01"), ("cam1", "Cam-B"), ("cam2", "c3")):
        (lab_root / f"raw/sessions/s00/{old}.mcap").rename(lab_root / f"raw/sessions/s00/{new}.mcap")
        (lab_root / f"raw/sessions/s00/openpose/{old}").rename(lab_root / f"raw/sessions/s00/openpose/{new}")
        (lab_root / f"raw/calibration/{old}").rename(lab_root / f"raw/calibration/{new}")
    write_config(lab_root, {**LAB, "lab": {**LAB["lab"], "cameras": ["cam_01", "Cam-B", "c3"]}})
    rules = scheduled_rules(snakemake(lab_root, "-n"))
    assert {"detection", "pose2d", "triangulation"} <= rules


@pytest.mark.parametrize("name", ["cam 1", "../cam1", "optitrack", "cam.1"])
def test_unusable_camera_names_are_refused(lab_root, name):
    write_config(lab_root, {**LAB, "lab": {**LAB["lab"], "cameras": [name, "cam1", "cam2"]}})
    proc = snakemake(lab_root, "-n", check=False)
    assert proc.returncode != 0 and f"lab.cameras: {name!r} is" in said(proc)


def test_the_default_source_refuses_to_simulate_over_a_labs_recordings(lab_root):
    """source: twin is the default: a lab that forgets source: lab gets an error, not its recordings
    replaced by the twin's."""
    before = raw_digest(lab_root)
    proc = snakemake(lab_root, configfile="config/test/tiny.yaml", check=False)
    assert proc.returncode != 0
    assert "files under raw/ were not written by the twin" in said(proc)
    assert "set source: lab (the README's 'Bringing your lab's recordings')" in said(proc)
    assert raw_digest(lab_root) == before


@pytest.mark.parametrize(("extrinsics", "needed"), [("table_mat", "table"), ("board", "extrinsics"),
                                                     ("points", None)])
def test_the_shot_each_extrinsics_method_needs(tmp_path, extrinsics, needed):
    """Each camera needs its board views and the extrinsics shot its method reads (none for scene points),
    in any image format; an imported calibration needs only its file."""
    for cam in ("c1", "c2"):
        (tmp_path / "raw/calibration" / cam).mkdir(parents=True)
        (tmp_path / f"raw/calibration/{cam}/intrinsics_00.JPG").write_bytes(b"")
    problems = lab_layout_problems(tmp_path, [], ["c1", "c2"], None, None, extrinsics)
    expected = [] if needed is None else [f"raw/calibration/{c}/{needed}.*: missing" for c in ("c1", "c2")]
    assert [p.split("; expected")[0] for p in problems if p.startswith("raw/")] == expected
    if needed:
        (tmp_path / f"raw/calibration/c1/{needed}.tif").write_bytes(b"")
        (tmp_path / f"raw/calibration/c2/{needed}.bmp").write_bytes(b"")
        assert not [p for p in lab_layout_problems(tmp_path, [], ["c1", "c2"], None, None, extrinsics)
                    if p.startswith("raw/")]
    assert lab_layout_problems(tmp_path, [], ["c1"], None, "rig.toml", extrinsics)[1].startswith(
        "rig.toml: missing (perception.calibration_import)")
