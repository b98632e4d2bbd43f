# Every target creates the virtual environment and installs the package when it is missing,
# so on a fresh machine `make test` and `make bench` are all a user types.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: venv test test-fast lint bench bench-micro models clean

venv: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[dev]"
	touch $(STAMP)

test: $(STAMP)
	$(PY) -m pytest -q

lint: $(STAMP)
	$(VENV)/bin/ruff check wbcbench tests benchmarks
	$(VENV)/bin/ruff format --check wbcbench tests benchmarks
	$(VENV)/bin/mypy wbcbench

models: $(STAMP)
	$(PY) -m wbcbench.robots.generator

bench: $(STAMP)
	$(VENV)/bin/wbcbench bench --out results

bench-micro: $(STAMP)
	$(PY) -m pytest -q benchmarks --benchmark-enable --benchmark-only

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .mypy_cache .ruff_cache
