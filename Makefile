# `make run`: set up and run the whole default pipeline; `make test`: set up and run the tests.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin

.PHONY: setup run test lint report clean

setup: $(VENV)/.installed

# torch first, pinned and through pip: that exact version is the CPU wheel on the build machines (pip's
# find-links; uv does not look there); the project's own `torch==2.13.0` requirement is then already met
# and pulls no CUDA packages. Everything else through uv (pinned), at the exact versions of
# constraints.txt, so that runs on different days give the same artifacts: the same packages as pip
# installs (checked: identical `pip list` but for pip and uv themselves); the whole setup 49-58 s, not ~100 s.
# Byte-compiled at install, as pip does and uv does not by default: where PYTHONDONTWRITEBYTECODE is set
# (these machines set it) every job would otherwise compile each module it imports, e.g. 1.45 s instead of
# 0.54 s to import twin_openpose's stage; the project's own src/ likewise.
UV_VERSION := 0.13.9

$(VENV)/.installed: pyproject.toml constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet torch==2.13.0 uv==$(UV_VERSION)
	$(BIN)/uv pip install --quiet --compile-bytecode --python $(BIN)/python -c constraints.txt -e ".[test]"
	$(BIN)/python -m compileall -q src
	touch $@

run: setup
	$(BIN)/snakemake

test: setup
	$(BIN)/python -m pytest -q

lint: setup
	$(BIN)/ruff check .
	$(BIN)/snakemake --lint

report: setup
	$(BIN)/snakemake --report reports/report.html

clean:
	rm -rf raw/* interim/* processed/* reports/tables/* reports/figures/* .snakemake
