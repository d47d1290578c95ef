# Two entry points for a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin

.PHONY: demo test lint typed bench clean

$(BIN)/python:
	$(PYTHON) -c 'import sys; assert sys.version_info >= (3, 11), "ikfusion needs Python >= 3.11"'
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip

$(VENV)/.installed: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install -q -e '.[view]'
	touch $@

$(VENV)/.installed-dev: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install -q -e '.[dev]'
	touch $@

demo: $(VENV)/.installed
	$(BIN)/ikfusion demo

lint: $(VENV)/.installed-dev
	$(BIN)/ruff check ikfusion tests benchmarks
	$(BIN)/mypy ikfusion

# the solver's modules compiled by mypyc (opt-in; once per source version, about two minutes)
typed: $(VENV)/.installed
	$(BIN)/python -m pip install -q -e '.[typed]'
	$(BIN)/python -m ikfusion.native.compile_typed

# (the build lets tests/test_typed_modules.py compare compiled and Python solves; without a
# compiler the build fails, with a warning, and those tests skip)
test: lint
	$(BIN)/python -m ikfusion.native.compile_typed || echo "warning: compiled modules not built"
	OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 $(BIN)/pytest -n 2 -q

bench: $(VENV)/.installed-dev
	for f in benchmarks/bench_*.py; do $(BIN)/python $$f || exit 1; done

clean:
	rm -rf $(VENV) ikfusion-demo .pytest_cache .mypy_cache .ruff_cache
