"""The workflow reruns exactly what changed: real rules on a tiny twin config, in a copy of the checkout.

Chain: twin_rig (cameras)   twin_simulate (per session) -> report_twin_flights (table).
"""

import pytest
from workflow_util import changed, copy_checkout, mtimes, snakemake, write_config

TINY = {"twin": {"n_sessions": 1, "rallies_per_session": 2, "n_cameras": 2, "width": 160, "height": 120}}
TARGETS = ["raw/twin_truth/rig.json", "reports/tables/twin_vs_real.md"]
SIMULATE = {f"raw/twin_truth/s00/{t}.parquet"
            for t in ("ball", "shots", "events", "people", "paddles", "strike_oracle")}
REPORT = {"reports/tables/twin_vs_real.md", "reports/tables/twin_vs_real.csv"}


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    root = copy_checkout(tmp_path_factory.mktemp("wf"))
    write_config(root, TINY)
    snakemake(root, *TARGETS)
    return root


def _rerun(root, *args, configfile="config/test.yaml"):
    before = mtimes(root)
    proc = snakemake(root, *TARGETS, *args, configfile=configfile)
    return changed(before, mtimes(root)), proc


def test_a_second_run_does_nothing(workdir):
    touched, proc = _rerun(workdir)
    assert touched == set()
    assert "Nothing to be done" in proc.stdout + proc.stderr


def test_b_param_change_reruns_the_stage_and_its_dependents_only(workdir):
    write_config(workdir, {"twin": {**TINY["twin"], "rallies_per_session": 3}})
    touched, _ = _rerun(workdir)
    assert touched == SIMULATE | REPORT  # not the rig
    write_config(workdir, TINY)
    touched, _ = _rerun(workdir)  # and back
    assert touched == SIMULATE | REPORT


def test_c_code_edit_reruns_the_stage_and_its_dependents_only(workdir):
    module = workdir / "src/pingpong/twin/session.py"  # imported by twin_simulate only
    module.write_text(module.read_text() + "\n# an edit\n")
    touched, _ = _rerun(workdir)
    assert touched == SIMULATE | REPORT
    report_only = workdir / "src/pingpong/reports/twin_flights.py"
    report_only.write_text(report_only.read_text() + "\n# an edit\n")
    touched, _ = _rerun(workdir)
    assert touched == REPORT
    rig = workdir / "src/pingpong/twin/rig.py"
    rig.write_text(rig.read_text() + "\n# an edit\n")
    touched, _ = _rerun(workdir)
    assert touched == {"raw/twin_truth/rig.json"}


def test_d_misspelled_key_fails_before_any_job(workdir):
    before = mtimes(workdir)
    write_config(workdir, {"twin": {**TINY["twin"], "ralies_per_session": 3}}, name="typo.yaml")
    proc = snakemake(workdir, *TARGETS, "--forceall", configfile="config/typo.yaml", check=False)
    assert proc.returncode != 0
    assert "config key 'twin': unknown key(s) ['ralies_per_session']" in proc.stderr
    assert mtimes(workdir) == before
