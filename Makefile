# Set-up and entry points. `make run` and `make test` each work from a fresh clone.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
DEV    := $(VENV)/.installed-dev
ARGS   ?=

.PHONY: install dev run full test mutants bench docs clean

# What `make run` needs: libLLVM, the venv, the package and its run-time dependencies.
install: $(STAMP)

# Also what the tests, benchmarks and docs tools need: the test and cluster extras
# (pytest, Playwright, markdown-it-py, Dask) and Chromium for the viewer's tests.
dev: $(DEV)

$(STAMP): pyproject.toml Makefile
	$(PYTHON) integrators/llvm.py --ensure
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	# compat: the editable install is a path entry (.pth), not an import hook, so that a
	# script beside a folder of its own named scenes/ (examples/) still imports this package
	$(BIN)/python -m pip install -q -e . --config-settings editable_mode=compat
	touch $@

$(DEV): $(STAMP)
	$(PYTHON) tools/ensure_browser.py --ensure || echo "warning: without Chromium the viewer tests (tests/test_viewer.py) fail; everything else works"
	$(BIN)/python -m pip install -q -e '.[test,cluster]' --config-settings editable_mode=compat
	touch $@

# The main job: the default experiments on the bundled scene, report in results/.
run: install
	$(BIN)/python -m experiments.run_all $(ARGS)

# The writeup's 1024x512 / 1000 spp bias checks as well (long).
full: install
	$(BIN)/python -m experiments.run_all --full $(ARGS)

# Two worker processes (pytest-xdist): most tests are bound by kernel compiles, which run
# on one core each (14 min in one process on the 2-core machine, 8 in two).
TEST_WORKERS ?= 2
test: dev
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) tests $(ARGS)

# Realistic bugs applied one at a time to a copy: the tests must fail on each (long).
mutants: dev
	$(BIN)/python -m tools.mutants $(ARGS)

# Benchmarks: results/bench.md and .json, and the table of docs/benchmarks.md.
bench: dev
	$(BIN)/python -m benchmarks.run --update-docs $(ARGS)

# The generated parts of the docs (docs/plugins.md, option tables, examples shown).
docs: dev
	$(BIN)/python -m tools.docs

clean:
	rm -rf results .pytest_cache
