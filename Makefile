# Two entry points that work on a fresh machine: `make demo` and `make test` (`make docs` builds
# the documentation site into docs/_build/html).
# Both create .venv (and install SuiteSparse headers with apt when missing) before running.
PY      ?= python3
VENV    := .venv
BIN     := $(VENV)/bin
STAMP   := $(VENV)/.installed
# numba's compiled kernels, shared by demo and test; the first run fills it (bfemp says so)
export NUMBA_CACHE_DIR ?= $(CURDIR)/.numba_cache

.PHONY: setup demo test docs lint format clean

setup: $(STAMP)

$(STAMP): pyproject.toml
	@if [ ! -f /usr/include/suitesparse/cholmod.h ]; then \
	  echo "installing SuiteSparse headers (libsuitesparse-dev)"; \
	  SUDO=$$(command -v sudo >/dev/null && [ "$$(id -u)" != 0 ] && echo sudo); \
	  $$SUDO apt-get update -qq && $$SUDO apt-get install -y -qq libsuitesparse-dev >/dev/null \
	    || echo "warning: could not install libsuitesparse-dev; bfemp will use the scipy fallback"; \
	fi
	@# OpenBLAS under CHOLMOD (1.4x-6.5x faster than the reference BLAS; never fails)
	@sh tools/install_openblas.sh
	@test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	@# the docs extra too: the tests build the documentation site (tests/test_docs.py)
	$(BIN)/python -m pip install -q -e ".[test,docs]"
	$(BIN)/python -m pip install -q "scikit-sparse<0.5" \
	  || echo "warning: scikit-sparse did not build; bfemp will use the scipy fallback"
	@$(BIN)/python -m bfemp --version
	@# compile the numba kernels once, 2D and 3D scenes side by side (about 2 min on 2 cores),
	@# so that the demo and the parallel test workers find them cached instead of each compiling
	$(BIN)/python -m bfemp warmup \
	  || echo "warning: bfemp warmup failed; the first run will compile the kernels itself"
	@touch $(STAMP)

demo: setup
	$(BIN)/python -m bfemp demo --out results/demo

# the documentation site: every gallery example runs, a warning fails the build
# (BFEMP_DOCS_QUICK=1 runs one example only; docs/README.md)
docs: setup
	$(BIN)/python -m sphinx -W --keep-going -b html docs docs/_build/html
	@echo "docs/_build/html/index.html"

lint: setup
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

format: setup
	$(BIN)/ruff format .
	$(BIN)/ruff check --fix .

# the test files in parallel (one worker per core, at most 4; a file's tests share a worker and
# its module fixtures), then the few tests that compare wall times, alone so no worker skews them
test: lint
	$(BIN)/python -m pytest -q -n auto --maxprocesses 4 --dist loadfile -m "not serial"
	$(BIN)/python -m pytest -q -m serial

clean:
	rm -rf $(VENV) .numba_cache results .pytest_cache docs/_build docs/generated docs/auto_examples
