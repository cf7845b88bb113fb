"""Two clean runs of the workflow give the same artifacts, byte for byte: every random draw is seeded
from the config and every stage's thread counts are fixed (`pingpong.common.script.pin_threads`)."""

import hashlib

import pytest
from conftest import TINY_CONFIG
from workflow_util import copy_checkout, snakemake

DATA_FOLDERS = ("raw", "interim", "processed", "reports")


def content_hashes(root) -> dict[str, str]:
    """SHA-256 of every artifact under the data folders, by path relative to the run's root."""
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for folder in DATA_FOLDERS for p in sorted((root / folder).rglob("*"))
            if p.is_file() and p.name != ".gitkeep"}


@pytest.mark.slow
def test_two_clean_runs_give_identical_artifacts(tiny_run, tmp_path):
    second = copy_checkout(tmp_path)
    snakemake(second, configfile=TINY_CONFIG)  # rule all, from clean, in another folder
    again, first = content_hashes(second), content_hashes(tiny_run)
    assert {p.split("/")[0] for p in again} == set(DATA_FOLDERS)
    assert any(p.endswith(".safetensors") for p in again)  # trained models are among them
    missing = sorted(set(again) - set(first))
    differ = sorted(p for p in again if p in first and first[p] != again[p])
    assert not missing and not differ, f"missing in the first run: {missing[:10]}; differ: {differ[:10]}"
