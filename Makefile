# `make run`: set up and run the whole default pipeline; `make test`: set up and run the tests.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin

.PHONY: setup setup-slurm run paper-scale test lint report clean

setup: $(VENV)/.installed

# Everything through uv (pinned), at the exact versions of constraints.txt, so that runs on different days
# give the same artifacts; torch is pinned in pyproject.toml. uv reads no pip configuration, so pip's
# find-links (where these machines keep torch's CPU wheel: without it the same pin takes the CUDA build
# of several GB) is passed on. uv installs torch in ~14 s where pip took ~27 s.
# Byte-compiled at install, as pip does and uv does not by default: where PYTHONDONTWRITEBYTECODE is set
# (these machines set it) every job would otherwise compile each module it imports, e.g. 1.45 s instead of
# 0.54 s to import twin_openpose's stage; the project's own src/ likewise.
# `make run` installs what the pipeline and `make report` import (snakemake[reports]: pygments); the tests
# add pytest and the rest of the `test` extra, the SLURM executor plugin among them.
UV_VERSION := 0.13.9
FIND_LINKS ?= $(or $(PIP_FIND_LINKS),$(shell $(PYTHON) -m pip config get global.find-links 2>/dev/null))
UV_INSTALL = $(BIN)/uv pip install --quiet --compile-bytecode --python $(BIN)/python -c constraints.txt \
	$(foreach d,$(FIND_LINKS),--find-links $(d))

$(VENV)/.installed: pyproject.toml constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet uv==$(UV_VERSION)
	$(UV_INSTALL) -e .
	$(BIN)/python -m compileall -q src
	touch $@

$(VENV)/.installed-test: $(VENV)/.installed
	$(UV_INSTALL) -e ".[test]"
	touch $@

# The SLURM executor plugin (for profiles/slurm) is a step of its own, asked for by name, rather than part of
# setup or installed wherever a SLURM client is found: every Snakemake start that has it imports it, and it
# asks the cluster for its configuration: 9 s per start where a SLURM client is installed and its controller
# is not running (a workstation with the client, a cluster while its controller is down), which a local run
# or a dry run should not pay; installed where `sbatch` is found, what setup makes would depend on PATH.
setup-slurm: $(VENV)/.installed-slurm

$(VENV)/.installed-slurm: $(VENV)/.installed
	$(UV_INSTALL) -e ".[slurm]"
	touch $@

run: setup
	$(BIN)/snakemake

# The paper's number of hits through every stage (issue 38), in a clone of its own (its artifacts share the
# default run's paths). Resumable: run it again and Snakemake goes on where it stopped (after a kill, unlock
# first: `$(BIN)/snakemake --unlock --configfile $(PAPER_SCALE_CONFIGS)`); each part's times are recorded in
# paper_scale_times.jsonl (checkpointed, so a killed part keeps its time), and analysis/paper_scale_summary.py
# writes docs/results/paper_scale.md.
PAPER_SCALE_CONFIGS := config/config.yaml config/paper_hits.yaml

paper-scale: setup
	$(BIN)/python analysis/timed_run.py paper_scale_times.jsonl -- $(BIN)/snakemake --rerun-incomplete \
		--configfile $(PAPER_SCALE_CONFIGS)

test: $(VENV)/.installed-test
	$(BIN)/python -m pytest -q --durations=25  # the slowest tests listed: CI time is watched

lint: $(VENV)/.installed-test
	$(BIN)/ruff check .
	$(BIN)/snakemake --lint

report: setup
	$(BIN)/snakemake --report reports/report.html

# The derived artifacts, and of raw/ only what the twin wrote with that very content (its records in
# raw/twin_truth/owned/): a lab's recordings stay, whatever their names (pingpong.common.raw_ownership;
# standard library only, so it runs without the environment).
clean:
	rm -rf interim/* processed/* reports/tables/* reports/figures/* reports/pages reports/report.html .snakemake
	PYTHONPATH=src $(PYTHON) -m pingpong.common.raw_ownership clean
