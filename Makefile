# Two commands on a fresh machine: `make demo` (install + fit a bundled dataset) and
# `make test` (install + run the default test suite). Both create .venv when it is missing.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.ipfit-installed
DEMO_OUT ?= demo-output

DOCS_STAMP := $(VENV)/.ipfit-docs-installed
DOCS_OUT ?= build/docs

.PHONY: demo lint test test-slow test-all bench bench-pipeline bench-peers reproduce docs dist wheel-smoke clean

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[test]'
	touch $(STAMP)

$(DOCS_STAMP): $(STAMP)
	$(BIN)/python -m pip install -q -e '.[docs]'
	touch $(DOCS_STAMP)

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
	$(BIN)/python benchmarks/bench_readers.py

# The recommended vs the paper's pipeline, `ipfit fit bunny`, and the scaling table up to a
# million points: docs/performance.md and docs/spurious.md (about half an hour on 2 cores).
bench-pipeline: $(STAMP)
	$(BIN)/python benchmarks/bench_pipeline.py

# ipfit against Open3D's screened Poisson (depth 6 and 8) on the bunny, the apple, the duck and the
# bunny's surface sampled to 10^6 points: docs/peers.md (Open3D installed with the test extra; about
# half an hour on 2 cores).
bench-peers: $(STAMP)
	$(BIN)/python benchmarks/bench_peers.py --million

reproduce: $(STAMP)
	$(BIN)/ipfit reproduce -o docs/reproduction

# The documentation site into $(DOCS_OUT)/html (open index.html): the user guide, the API reference and
# the gallery, whose examples run during the build. Nitpicky, warnings are errors; then no internal
# link may be broken and every public name must have its page (docs/site/check_site.py).
docs: $(DOCS_STAMP)
	$(BIN)/sphinx-build -W --keep-going -n -q -b html -c docs/site -d $(DOCS_OUT)/doctrees docs $(DOCS_OUT)/html
	$(BIN)/python docs/site/check_site.py $(DOCS_OUT)/html
	@echo "The site: $(DOCS_OUT)/html/index.html"

# sdist and wheel into dist/ (an isolated build with the build-system requirements of pyproject.toml)
dist: $(STAMP)
	$(BIN)/python -m pip install -q build
	rm -rf dist
	$(BIN)/python -m build -q --outdir dist .

# the wheel installed in a fresh virtual environment: the command line and the smoke tests against it
wheel-smoke: dist
	PYTHON=$(PYTHON) bash .ci/wheel-smoke

clean:
	rm -rf $(VENV) $(DEMO_OUT) .pytest_cache .mypy_cache .ruff_cache .import_linter_cache build dist \
		docs/site/generated docs/site/gallery docs/sg_execution_times.rst
