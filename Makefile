# Every target creates the virtual environment and installs the package when it is missing,
# so on a fresh machine `make test` and `make bench` are all a user types.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

# The tested dependency set: every distribution at an exact version (pip-compile's output).
# The environment is rebuilt from scratch whenever the lock or pyproject.toml changes, so it
# holds exactly what the lock says; `pip check` proves the set consistent.
LOCK              := requirements/lock.txt
PIP_VERSION       := 26.3
PIP_TOOLS_VERSION := 7.6.2
LOCK_VENV         := .venv-lock
LOCK_FLAGS        := --extra dev --extra robots --extra icub --extra peers --extra qpbench --all-build-deps --allow-unsafe --strip-extras \
                     --no-emit-index-url --no-emit-find-links --no-emit-trusted-host

.PHONY: venv native test test-numerics test-fast lint bench bench-full bench-micro qp-test-set reference models clean lock upgrade

venv: $(STAMP)

$(STAMP): pyproject.toml $(LOCK)
	rm -rf $(VENV)
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet pip==$(PIP_VERSION)
	$(PY) -m pip install --quiet --no-deps -r $(LOCK)
	$(PY) -m pip install --quiet --no-deps --no-build-isolation -e .
	$(PY) -m pip check
	touch $(STAMP)

# After editing the C++ of wbcbench/_native/src: rebuild the module; the build folder (build/)
# persists, so only what changed recompiles.
native: $(STAMP)
	$(PY) -m pip install --quiet --no-deps --no-build-isolation -e .

# pip-tools lives in its own environment, so that the tested one holds only the lock
$(LOCK_VENV)/bin/pip-compile:
	$(PYTHON) -m venv $(LOCK_VENV)
	$(LOCK_VENV)/bin/python -m pip install --quiet pip==$(PIP_VERSION) pip-tools==$(PIP_TOOLS_VERSION)

# After editing pyproject.toml's dependencies: re-resolve, keeping every existing pin it can.
lock: $(LOCK_VENV)/bin/pip-compile
	$(LOCK_VENV)/bin/pip-compile --quiet $(LOCK_FLAGS) --output-file $(LOCK) pyproject.toml

# The newest versions pyproject.toml allows: rewrite the lock, show what moved, run the tests.
upgrade: $(LOCK_VENV)/bin/pip-compile
	grep -E '^[A-Za-z0-9]' $(LOCK) > $(LOCK_VENV)/before.txt
	$(LOCK_VENV)/bin/pip-compile --quiet --upgrade $(LOCK_FLAGS) --output-file $(LOCK) pyproject.toml
	grep -E '^[A-Za-z0-9]' $(LOCK) > $(LOCK_VENV)/after.txt
	@echo "== what the upgrade changed (< before, > after):"
	@diff $(LOCK_VENV)/before.txt $(LOCK_VENV)/after.txt | grep '^[<>]' || echo "   nothing: the lock is current"
	@$(MAKE) --no-print-directory test || { echo "== the tests FAIL with the upgraded lock;" \
		"'git checkout $(LOCK)' returns to the tested set"; exit 1; }

# One worker per core (pytest-xdist); each worker runs its tests with one BLAS thread. The tests
# run in a random order (pytest-randomly) whose seed is printed first: `make test SEED=<n>`
# repeats that order. No test may take longer than pytest-timeout's limit (pyproject.toml).
ifndef SEED
SEED := $(shell od -An -N4 -tu4 /dev/urandom | tr -d ' ')
endif

test: $(STAMP)
	@echo "== the test order's seed: $(SEED) (make test SEED=$(SEED) repeats it)"
	$(PY) -m pytest -q -n auto --randomly-seed=$(SEED)

# The tests whose answers depend on floating-point rounding: CI runs them a second time under
# another BLAS kernel (OPENBLAS_CORETYPE) and another random order, to show that they assert
# what the methods guarantee, not one CPU's rounding.
NUMERICS := tests/test_native_equality.py tests/test_native_hierarchy.py tests/test_native_hls.py \
            tests/test_native_rc_lqp.py tests/test_native_reduced.py tests/test_native_solvers.py \
            tests/test_native_dynamics.py tests/test_oracle.py tests/test_hierarchy.py \
            tests/test_hls.py tests/test_hqp.py tests/test_kin_hqp.py tests/test_qp.py \
            tests/test_qp_backends.py

test-numerics: $(STAMP)
	@echo "== numerics under OPENBLAS_CORETYPE=$${OPENBLAS_CORETYPE:-<detected>}," \
		"the test order's seed: $(SEED)"
	$(PY) -m pytest -q -n auto --randomly-seed=$(SEED) $(NUMERICS)

lint: $(STAMP)
	$(VENV)/bin/ruff check wbcbench tests benchmarks examples
	$(VENV)/bin/ruff format --check wbcbench tests benchmarks examples
	$(VENV)/bin/mypy wbcbench examples/plugin/src

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

# The QP test set for solver developers: dump whole tick sequences, export them in qpbenchmark's
# layout (results/qp_test_set/), then solve them tick after tick with every backend.
qp-test-set: $(STAMP)
	$(VENV)/bin/wbcbench sweep sweeps/qp_test_set.yaml --out results/qp_sequences --executor serial
	$(VENV)/bin/wbcbench export-qps results/qp_sequences --out results/qp_test_set
	$(VENV)/bin/wbcbench solvers --sequences results/qp_test_set

# the small curated results the notebooks and the report tests read (results/reference/): the
# runs of sweeps/reference.yaml, copied from make bench's results/ where it holds them for this
# code (so the reference is what make bench measured; run it on a quiet machine first), the
# rest computed here
reference: $(STAMP)
	rm -rf results/reference
	$(VENV)/bin/wbcbench bench --sweep sweeps/reference.yaml --out results/reference --executor serial --no-progress --reuse results
	rm -rf results/reference/recordings results/reference/problems results/reference/*.parquet \
		results/reference/figures/*.svg

clean:
	rm -rf $(VENV) $(LOCK_VENV) build *.egg-info .pytest_cache .mypy_cache .ruff_cache
