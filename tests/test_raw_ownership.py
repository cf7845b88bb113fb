"""raw/ by content: what the twin wrote is recorded with its SHA-256, and no rule or `make clean` replaces,
moves or deletes anything else there, under any source and whatever ran before (issue 48's scenarios)."""

import hashlib
import json
import os
import shutil
import subprocess

import pytest
from hypothesis import given
from hypothesis import strategies as st
from workflow_util import ROOT, copy_checkout, snakemake, write_config

from pingpong.common import atomic, raw_ownership
from pingpong.common.raw_ownership import OWNED, STAT_CACHE, clean, foreign_files, recording

TWIN = "config/test/tiny.yaml"


def raw_sha256(root) -> dict[str, str]:
    """SHA-256 of every file under raw/."""
    return {p.relative_to(root).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted((root / "raw").rglob("*")) if p.is_file()}


def lab_files(root) -> dict[str, str]:
    return {k: v for k, v in raw_sha256(root).items() if not k.startswith(OWNED)}


def write_as_job(root, stage, files: dict[str, bytes], folder: str | None = None, fail=False):
    """What a twin job does: its outputs under raw/ written atomically inside `recording`."""
    outputs = [str(root / f) for f in files] + ([str(root / folder)] if folder else [])
    with recording(stage, outputs, root):
        for name, data in files.items():
            atomic.write_bytes_atomic(root / name, data)
        if folder:
            with atomic.atomic_dir(root / folder) as tmp:
                (tmp / "f_000.json").write_text("{}")
                (tmp / "f_001.json").write_text('{"people": []}')
        if fail:
            raise KeyboardInterrupt  # killed after its renames, before the job's end


def test_what_a_job_writes_is_its_own_and_anything_else_is_named(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    write_as_job(tmp_path, "twin_rig", {"raw/twin_truth/rig.json": b"{}"},
                 folder="raw/sessions/s00/openpose/cam0")
    assert foreign_files(tmp_path) == []
    (tmp_path / "raw/sessions/s00/openpose/cam0/lab_000.json").write_text("{}")  # a lab's file in the folder
    (tmp_path / "raw/twin_truth/rig.json").write_bytes(b"{ }")  # changed since the twin wrote it
    assert foreign_files(tmp_path) == ["raw/sessions/s00/openpose/cam0/lab_000.json",
                                       "raw/twin_truth/rig.json"]
    with pytest.raises(raw_ownership.RawOwnershipError, match="2 files under raw/ were not written"):
        raw_ownership.check(tmp_path)


def test_a_copy_of_the_twins_content_is_hashed_and_accepted(tmp_path, monkeypatch):
    """A copy has a new inode and ctime, so it is read again: equal bytes are the twin's bytes."""
    monkeypatch.chdir(tmp_path)
    write_as_job(tmp_path, "twin_rig", {"raw/twin_truth/rig.json": b'{"a": 1}'})
    rig = tmp_path / "raw/twin_truth/rig.json"
    data = rig.read_bytes()
    rig.unlink()
    rig.write_bytes(data)
    assert foreign_files(tmp_path) == []


def test_the_stat_cache_never_vouches_for_changed_bytes(tmp_path, monkeypatch):
    """A file written over in place, same size, its mtime set back (what `cp -p` or `touch -d` can do):
    its ctime moved, so it is read again and refused."""
    monkeypatch.chdir(tmp_path)
    write_as_job(tmp_path, "twin_rig", {"raw/twin_truth/rig.json": b'{"a": 1}'})
    rig = tmp_path / "raw/twin_truth/rig.json"
    assert foreign_files(tmp_path) == [] and (tmp_path / STAT_CACHE).is_file()
    st = rig.stat()
    with open(rig, "r+b") as f:
        f.write(b'{"a": 2}')
    os.utime(rig, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert foreign_files(tmp_path) == ["raw/twin_truth/rig.json"]


def test_a_job_killed_after_its_renames_still_owns_them(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(KeyboardInterrupt):
        write_as_job(tmp_path, "twin_camera", {"raw/sessions/s00/cam0.mcap": b"mcap"},
                     folder="raw/sessions/s00/openpose/cam0", fail=True)
    assert [p.suffix for p in (tmp_path / OWNED).iterdir()] == [".pending"]
    assert foreign_files(tmp_path) == []
    (tmp_path / STAT_CACHE).unlink()
    write_as_job(tmp_path, "twin_camera", {"raw/sessions/s00/cam0.mcap": b"mcap2"},
                 folder="raw/sessions/s00/openpose/cam0")  # the rerun: one record, no pending
    assert [p.suffix for p in (tmp_path / OWNED).iterdir()] == [".sha256"]
    assert foreign_files(tmp_path) == []


def test_a_job_writing_outside_raw_records_nothing(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    write_as_job(tmp_path, "detection", {"interim/detections/s00/cam0.parquet": b"x"})
    assert not (tmp_path / OWNED).exists()


def test_temporaries_and_markers_are_nobodys_files(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "raw/sessions/s00/openpose/cam0").mkdir(parents=True)
    (tmp_path / "raw/.gitkeep").write_text("")
    (tmp_path / "raw/sessions/s00/.cam0.mcap.ab12cd_9.tmp").write_bytes(b"half")  # a killed atomic write
    (tmp_path / "raw/sessions/s00/openpose/cam0/.snakemake_timestamp").write_text("")
    assert foreign_files(tmp_path) == []


@given(st.lists(st.tuples(st.sampled_from(["twin", "lab", "twin_then_lab"]), st.binary(max_size=8)),
                min_size=1, max_size=8))
def test_clean_removes_exactly_the_twins_unchanged_files(tmp_path_factory, files):
    """Whatever the mix of the twin's files, a lab's files and twin files a lab wrote over, clean removes
    the first and leaves the others byte for byte."""
    root = tmp_path_factory.mktemp("clean")
    expect_kept = {}
    for i, (who, data) in enumerate(files):
        name = f"raw/sessions/s{i % 3:02d}/f{i}.bin"
        if who != "lab":
            write_as_job(root, f"twin_{i}", {name: data})
        if who != "twin":
            (root / name).parent.mkdir(parents=True, exist_ok=True)
            (root / name).write_bytes(data + b"lab")
            expect_kept[name] = hashlib.sha256(data + b"lab").hexdigest()
    removed, kept = clean(root)
    assert lab_files(root) == expect_kept and sorted(kept) == sorted(expect_kept)
    assert len(removed) == sum(who == "twin" for who, _ in files)
    assert not (root / OWNED).exists()
    sessions = root / "raw/sessions"
    assert all(any(p.iterdir()) for p in (sessions.iterdir() if sessions.exists() else []))  # none left empty


# The three scenarios of issue 48, in the workflow as users run it.

@pytest.fixture
def twin_wrote_raw(tmp_path):
    """A checkout where the twin has written its rig (as `make run` does first)."""
    root = copy_checkout(tmp_path)
    snakemake(root, "raw/twin_truth/rig.json", configfile=TWIN)
    return root


def lab_openpose(folder, n=5):
    """A lab's OpenPose JSON files (content the twin never wrote)."""
    folder.mkdir(parents=True, exist_ok=True)
    for i in range(n):
        person = {"version": 1.3, "people": [], "lab_frame": i}
        (folder / f"lab_{i:012d}_keypoints.json").write_text(json.dumps(person))


def test_a_labs_folder_under_a_twin_name_stops_the_twin_before_any_job(twin_wrote_raw):
    """Scenario 1: after the twin wrote raw/, a lab session under a twin name (s00, cam0) is refused by
    the dry run and the run, naming its files; raw/ stays byte-identical."""
    root = twin_wrote_raw
    lab_openpose(root / "raw/sessions/s00/openpose/cam0")
    before = raw_sha256(root)
    for args in (["-n"], ["--until", "twin_openpose"]):
        proc = snakemake(root, *args, configfile=TWIN, check=False)
        said = proc.stdout + proc.stderr
        assert proc.returncode != 0
        assert "5 files under raw/ were not written by the twin" in said
        assert "raw/sessions/s00/openpose/cam0/lab_000000000000_keypoints.json" in said
        assert "Nothing was run" in said
        assert raw_sha256(root) == before


def test_make_clean_keeps_a_labs_files(twin_wrote_raw):
    """Scenario 2: `make clean` removes the twin's own files and the derived artifacts, never a lab's,
    wherever they lie (under a twin name too)."""
    root = twin_wrote_raw
    lab_openpose(root / "raw/sessions/lab01/openpose/cam_01")
    (root / "raw/sessions/lab01/cam_01.mp4").write_bytes(b"\x00\x00\x00\x18ftypmp42 a lab's video")
    lab_openpose(root / "raw/sessions/s00/openpose/cam0", n=2)
    (root / "raw/twin_truth/rig.json").write_text('{"the lab": "edited the twin\'s rig"}')
    (root / "interim/detections").mkdir(parents=True)
    (root / "interim/detections/x.parquet").write_bytes(b"derived")
    lab = lab_files(root)
    proc = subprocess.run(["make", "clean"], cwd=root, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert lab_files(root) == lab
    assert "kept 9 files it did not write" in proc.stdout
    assert not (root / "interim/detections").exists() and (root / "interim/.gitkeep").exists()


def test_make_clean_removes_every_file_the_twin_wrote(twin_wrote_raw):
    proc = subprocess.run(["make", "clean"], cwd=twin_wrote_raw, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert [p.name for p in (twin_wrote_raw / "raw").iterdir()] == [".gitkeep"]


def test_a_configured_camera_without_a_video_stops_the_dry_run(tiny_run, tmp_path):
    """Scenario 3: under source: lab a camera listed without its recording is named before any job
    (no camera silently dropped); the lab's files stay byte-identical."""
    root = copy_checkout(tmp_path)
    for folder in ("raw/calibration", "raw/sessions/s00"):
        shutil.copytree(tiny_run / folder, root / folder)
    (root / "raw/sessions/s00/cam2.mcap").unlink()
    write_config(root, {"source": "lab", "lab": {"sessions": ["s00"], "cameras": ["cam0", "cam1", "cam2"]}})
    before = raw_sha256(root)
    for args in (["-n"], []):
        proc = snakemake(root, *args, check=False)
        said = proc.stdout + proc.stderr
        assert proc.returncode != 0
        assert "raw/sessions/s00/cam2.*: missing; expected camera cam2's recording" in said
        assert raw_sha256(root) == before


def test_the_makefile_clean_target_deletes_nothing_by_pattern():
    """`make clean` names no raw/ path of its own: raw/ is only ever cleaned through the records."""
    recipe = subprocess.run(["make", "-n", "clean"], cwd=ROOT, capture_output=True, text=True).stdout
    assert "raw" not in recipe.replace("pingpong.common.raw_ownership", "")
