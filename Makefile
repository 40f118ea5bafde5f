# Two commands on a fresh machine: `make demo` (install + fit a bundled dataset) and
# `make test` (install + run the default test suite). Both create .venv when it is missing.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.ipfit-installed
DEMO_OUT ?= demo-output

.PHONY: demo test test-slow test-all bench reproduce clean

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[test]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/ipfit fit boot --output $(DEMO_OUT)/boot
	@echo "Outputs written to $(DEMO_OUT)/"

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

reproduce: $(STAMP)
	$(BIN)/ipfit reproduce --out docs/reproduction

clean:
	rm -rf $(VENV) $(DEMO_OUT) .pytest_cache
