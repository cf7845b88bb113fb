"""The artifact helper: round trip, provenance metadata, atomic writes, schema checks."""

import hashlib
import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
import torch

from pingpong import __version__
from pingpong.common.artifacts import (
    ArtifactError,
    Provenance,
    Schema,
    load_model,
    read_json,
    read_metadata,
    read_table,
    save_model,
    write_json,
    write_table,
)

BALL = Schema("ball3d", 2, ("time_ns", "x"))


def _df():
    return pd.DataFrame({"time_ns": np.arange(5, dtype=np.int64) * 10_000_000, "x": np.linspace(0, 1, 5)})


def test_round_trip_keeps_data_and_provenance(tmp_path):
    src = tmp_path / "input.bin"
    src.write_bytes(b"raw")
    prov = Provenance.of("triangulation", {"min_views": 2}, "abc123", [src])
    write_table(_df(), tmp_path / "a.parquet", BALL, prov)
    pd.testing.assert_frame_equal(read_table(tmp_path / "a.parquet", BALL), _df())
    meta = read_metadata(tmp_path / "a.parquet")
    assert meta["schema"] == "ball3d" and meta["schema_version"] == 2
    assert meta["stage"] == "triangulation" and meta["code_hash"] == "abc123"
    assert meta["package_version"] == __version__
    assert len(meta["params_hash"]) == 64
    assert meta["inputs"] == {str(src): hashlib.sha256(b"raw").hexdigest()}


def test_params_hash_ignores_key_order_but_not_values():
    a = Provenance.of("s", {"a": 1, "b": [1, 2]})
    assert a.params_hash == Provenance.of("s", {"b": [1, 2], "a": 1}).params_hash
    assert a.params_hash != Provenance.of("s", {"a": 2, "b": [1, 2]}).params_hash


def test_wrong_schema_name_and_versions_fail_clearly(tmp_path):
    path = tmp_path / "a.parquet"
    write_table(_df(), path, BALL, Provenance.of("s"))
    with pytest.raises(ArtifactError, match="holds schema 'ball3d', expected 'pose3d'"):
        read_table(path, Schema("pose3d", 2))
    with pytest.raises(ArtifactError, match="newer pipeline"):
        read_table(path, Schema("ball3d", 1))
    with pytest.raises(ArtifactError, match="rebuild it"):
        read_table(path, Schema("ball3d", 3))


def test_plain_parquet_without_provenance_is_refused(tmp_path):
    path = tmp_path / "plain.parquet"
    _df().to_parquet(path)
    with pytest.raises(ArtifactError, match="no pingpong provenance"):
        read_table(path, BALL)


def test_missing_columns_are_refused_on_write(tmp_path):
    with pytest.raises(ArtifactError, match=r"needs columns \['x'\]"):
        write_table(_df()[["time_ns"]], tmp_path / "a.parquet", BALL, Provenance.of("s"))
    assert not (tmp_path / "a.parquet").exists()


def test_failure_mid_write_leaves_no_file_and_keeps_the_old_one(tmp_path, monkeypatch):
    path = tmp_path / "a.parquet"
    write_table(_df(), path, BALL, Provenance.of("s"))
    before = path.read_bytes()

    def crash(table, where, **kw):
        with open(where, "wb") as f:
            f.write(b"PAR1 half a file")
        raise OSError("disk full")

    monkeypatch.setattr(pq, "write_table", crash)
    with pytest.raises(OSError):
        write_table(_df().assign(x=7.0), path, BALL, Provenance.of("s"))
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["a.parquet"]


def test_killed_process_leaves_no_file_under_the_final_name(tmp_path):
    """SIGKILL while the temporary file is being written: the final name never appears."""
    path = tmp_path / "big.parquet"
    code = textwrap.dedent(f"""
        import os, sys, pyarrow.parquet as pq, pandas as pd
        from pingpong.common.artifacts import Schema, Provenance, write_table
        real = pq.write_table
        def slow(table, where, **kw):
            real(table, where, **kw)
            print("written-temp", flush=True)
            sys.stdin.readline()  # hang here until killed
        pq.write_table = slow
        write_table(pd.DataFrame({{"x": [1.0]}}), {str(path)!r}, Schema("t", 1), Provenance.of("s"))
    """)
    proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            text=True)
    assert proc.stdout.readline().strip() == "written-temp"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert not path.exists()


def test_json_artifact_round_trip_and_version_check(tmp_path):
    path = tmp_path / "cameras.json"
    schema = Schema("cameras", 1)
    write_json({"cams": [1, 2]}, path, schema, Provenance.of("calibration"))
    assert read_json(path, schema) == {"cams": [1, 2]}
    assert json.loads(path.read_text())["_provenance"]["stage"] == "calibration"
    with pytest.raises(ArtifactError, match="version 1"):
        read_json(path, Schema("cameras", 2))


def test_model_round_trip_without_pickle(tmp_path):
    schema = Schema("model", 1)
    tensors = {"w": torch.arange(6, dtype=torch.float32).reshape(2, 3), "b": torch.ones(3)}
    save_model(tensors, {"hidden": 100, "cell": "gru"}, tmp_path / "m", schema, Provenance.of("training"))
    loaded, hparams = load_model(tmp_path / "m", schema)
    assert hparams == {"hidden": 100, "cell": "gru"}
    assert torch.equal(loaded["w"], tensors["w"]) and torch.equal(loaded["b"], tensors["b"])
    assert (tmp_path / "m.safetensors").read_bytes()[:8] != b"\x80\x04\x95"  # not a pickle


def test_content_hash_ignores_provenance_but_not_data(tmp_path):
    from pingpong.common.content import compare_runs, content_sha256

    for run, code in (("a", "code1"), ("b", "code2")):
        (tmp_path / run / "processed").mkdir(parents=True)
        write_table(_df(), tmp_path / run / "processed/t.parquet", BALL, Provenance.of("s", {}, code))
        write_json({"k": 1}, tmp_path / run / "processed/j.json", BALL, Provenance.of("s", {}, code))
    a, b = tmp_path / "a/processed", tmp_path / "b/processed"
    assert (a / "t.parquet").read_bytes() != (b / "t.parquet").read_bytes()  # the code hash differs
    assert content_sha256(a / "t.parquet") == content_sha256(b / "t.parquet")
    assert content_sha256(a / "j.json") == content_sha256(b / "j.json")
    write_table(_df().assign(x=_df()["x"] + 1e-12), b / "t.parquet", BALL, Provenance.of("s"))
    write_json({"k": 2}, b / "j.json", BALL, Provenance.of("s"))
    (b / "extra.md").write_text("x")
    diff = compare_runs(tmp_path / "a", tmp_path / "b")
    assert diff == {"only_in_a": [], "only_in_b": ["processed/extra.md"],
                    "differ": ["processed/j.json", "processed/t.parquet"]}


def test_what_c_code_writes_on_fd2_reaches_the_stage_log(tmp_path):
    """run_rule points file descriptor 2 at the rule's log: libjpeg's and FFmpeg's warnings land there."""
    script = textwrap.dedent("""
        import os, sys
        from pingpong.common.stderr import fd2_onto
        with open(sys.argv[1], "w", buffering=1) as log, fd2_onto(log.fileno()):
            os.write(2, b"Corrupt JPEG data: 3 extraneous bytes\\n")
        os.write(2, b"after the block\\n")
    """)
    log = tmp_path / "stage.log"
    proc = subprocess.run([sys.executable, "-c", script, str(log)], capture_output=True, text=True,
                          check=True)
    assert log.read_text() == "Corrupt JPEG data: 3 extraneous bytes\n"
    assert proc.stderr == "after the block\n"  # fd 2 restored


def test_a_failing_stage_writes_its_traceback_to_its_log(tmp_path):
    """The error of a rule's job is in the log its Snakemake message points to (here: a param not given)."""
    log = tmp_path / "report_sync.log"
    stage = Path(__file__).resolve().parents[1] / "workflow" / "scripts" / "stage.py"
    proc = subprocess.run([sys.executable, str(stage), "report_sync", "--log", str(log)], capture_output=True,
                          text=True)
    assert proc.returncode != 0
    text = log.read_text()
    assert "rule report_sync failed" in text and "Traceback" in text and "KeyError: 'sessions'" in text
