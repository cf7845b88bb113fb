"""One local GPU: profiles/gpu runs the training rules on it, N at a time (a `gpu` resource), and a fold
trained on CUDA agrees with the same fold trained on the CPU (that part runs only where CUDA is)."""

import re

import numpy as np
import pytest
import torch
import yaml
from conftest import TINY_CONFIG
from workflow_util import DEFAULTS, ROOT, copy_checkout, snakemake

from pingpong.common.artifacts import read_table
from pingpong.curation.schemas import DATASET, dataset_arrays
from pingpong.learning.cv import TrainSettings, fit_fold
from pingpong.learning.grid import expand_grid

PROFILE = ROOT / "profiles/gpu/config.yaml"
TORCH_RULES = {"train_cv", "train_final"}  # the rules that train on config `device`


def _profile_value(items: list, key: str) -> str:
    """`key=value` items of a profile list (Snakemake's --config / --resources) -> value of `key`."""
    found = dict(item.split("=", 1) for item in items)
    return found[key]


def test_gpu_profile_asks_for_cuda_and_caps_the_gpu_jobs():
    profile = yaml.safe_load(PROFILE.read_text())
    assert _profile_value(profile["config"], "device") == "cuda"
    assert int(_profile_value(profile["resources"], "gpu")) >= 1
    assert profile["cores"] == "all"


def _jobs_resources(dry_run: str) -> list[tuple[str, dict]]:
    """(rule, resources) of every job block of a dry run's output."""
    jobs = []
    for block in re.split(r"\n(?=\[[^\]]+\]\n(?:local)?rule )", dry_run):
        rule = re.search(r"^(?:local)?rule (\w+):", block, re.M)
        res = re.search(r"^\s+resources: (.*)$", block, re.M)
        if rule:
            pairs = [kv.split("=", 1) for kv in res.group(1).split(", ")] if res else []
            jobs.append((rule.group(1), dict(pairs)))
    return jobs


@pytest.mark.slow
def test_gpu_profile_schedules_the_training_rules_on_the_gpu(tmp_path):
    """A dry run of the tiny config under the profile: every training job asks for one GPU, no other job
    for any; and Snakemake reads the profile's total (its cap on training jobs at once)."""
    root = copy_checkout(tmp_path)
    out = snakemake(root, "-n", "--profile", "profiles/gpu", configfile=TINY_CONFIG).stdout
    jobs = _jobs_resources(out)
    rules = {rule for rule, _ in jobs}
    assert TORCH_RULES <= rules and "dataset" in rules
    for rule, resources in jobs:
        assert resources.get("gpu") == ("1" if rule in TORCH_RULES else None), (rule, resources)
    # the profile's `resources: gpu=N` as Snakemake parses it (its cli's own parser, profile included)
    from snakemake.cli import parse_args
    _, args = parse_args(["--profile", str(PROFILE.parent), "-n"])
    total = _profile_value(yaml.safe_load(PROFILE.read_text())["resources"], "gpu")
    assert args.resources["gpu"].value == int(total)


@pytest.mark.slow
@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_one_fold_on_cuda_agrees_with_the_cpu(tiny_run):
    """The default net (the schema's default grid's first configuration) on fold 0 of the tiny run's
    training hits, 10 epochs, on CUDA and on the CPU: validation losses within 5 % of each other, and two
    CUDA runs the same. Tolerance: other kernels sum in other orders and training grows those last-bit
    differences; issue 38 measured 3.60 against 3.58 (0.6 %) after full early-stopped training on an H200,
    and a device bug (a tensor left on the CPU, a mask not moved) moves the loss by far more."""
    dataset = read_table(tiny_run / "processed/dataset.parquet", DATASET)
    train = dataset[dataset["split"] == "train"]
    X, Y = dataset_arrays(train)
    folds = train["fold"].to_numpy()
    config = expand_grid(DEFAULTS["training"]["grid"])[0]
    settings = {k: DEFAULTS["training"][k] for k in ("batch_size", "patience", "min_delta",
                                                     "early_frame_weight", "reflect_augment")}
    losses = {}
    for run, device in (("cpu", "cpu"), ("cuda", "cuda"), ("cuda again", "cuda")):
        fitted = TrainSettings(max_epochs=10, device=device, **settings)
        _, result = fit_fold(X, Y, folds, 0, config, fitted, seed=0)
        losses[run] = result["val_loss"]
    assert np.isfinite(list(losses.values())).all()
    assert losses["cuda"] == pytest.approx(losses["cpu"], rel=0.05), losses
    assert losses["cuda again"] == pytest.approx(losses["cuda"], rel=1e-6), losses  # deterministic on CUDA
