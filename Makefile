# Every target creates the virtual environment and installs the package when it is missing,
# so on a fresh machine `make test` and `make bench` are all a user types.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: venv test test-fast lint bench bench-full bench-micro reference models clean

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

# Closed-loop tracking runs go to a local dask cluster (one worker per core); timing runs are
# always serial. BENCH_EXECUTOR=serial runs everything in one process.
BENCH_EXECUTOR ?= dask

bench: $(STAMP)
	$(VENV)/bin/wbcbench bench --sweep sweeps/default.yaml --out results --executor $(BENCH_EXECUTOR)

bench-full: $(STAMP)
	$(VENV)/bin/wbcbench bench --sweep sweeps/full.yaml --out results/full --executor $(BENCH_EXECUTOR)

# the micro-benchmarks are bench_*.py files: name them for pytest explicitly
bench-micro: $(STAMP)
	$(PY) -m pytest -q benchmarks -o python_files="bench_*.py" --benchmark-enable --benchmark-only

# the small curated results the notebooks and the report tests read (results/reference/)
reference: $(STAMP)
	rm -rf results/reference
	$(VENV)/bin/wbcbench bench --sweep sweeps/reference.yaml --out results/reference --executor serial --no-progress
	rm -rf results/reference/recordings results/reference/problems results/reference/*.parquet \
		results/reference/figures/*.svg

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .mypy_cache .ruff_cache
