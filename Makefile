# Two commands on a fresh machine: `make demo` (install + fit a bundled dataset) and
# `make test` (install + run the default test suite). Both create .venv when it is missing.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.ipfit-installed
DEMO_OUT ?= demo-output

.PHONY: demo lint test test-slow test-all bench bench-pipeline reproduce clean

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[test]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/ipfit fit boot --output $(DEMO_OUT)/boot
	@echo "Outputs written to $(DEMO_OUT)/"

# ruff, mypy and the import-layer contract (.importlinter): configured in pyproject.toml; run by CI before the tests
lint: $(STAMP)
	$(BIN)/ruff check src/ipfit
	$(BIN)/mypy
	$(BIN)/lint-imports

test: $(STAMP)
	$(BIN)/python -m pytest

test-slow: $(STAMP)
	$(BIN)/python -m pytest -m slow

test-all: $(STAMP)
	$(BIN)/python -m pytest -m ''

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_normals.py
	$(BIN)/python benchmarks/bench_objective.py
	$(BIN)/python benchmarks/bench_zeroset.py
	$(BIN)/python benchmarks/bench_farfield.py
	$(BIN)/python benchmarks/bench_polish.py

# The recommended vs the paper's pipeline, `ipfit fit bunny`, and the scaling table up to a
# million points: docs/performance.md and docs/spurious.md (about half an hour on 2 cores).
bench-pipeline: $(STAMP)
	$(BIN)/python benchmarks/bench_pipeline.py

reproduce: $(STAMP)
	$(BIN)/ipfit reproduce -o docs/reproduction

clean:
	rm -rf $(VENV) $(DEMO_OUT) .pytest_cache .mypy_cache .ruff_cache .import_linter_cache
