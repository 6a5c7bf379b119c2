# Two entry points for a fresh machine: `make demo` and `make test`.
# Both bootstrap the project's own virtual environment in .venv.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

UV_VERSION := 0.13.9

.PHONY: demo test lint house bench bench-console bench-serve bench-bytes bench-consoles bench-fanout bench-telemetry venv screenshots lock

# The exact, hash-checked versions of requirements.lock: every machine installs what the suite was
# last green with. pyproject.toml keeps ranges for people who install the package as a library.
$(STAMP): pyproject.toml requirements.lock
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --require-hashes -r requirements.lock
	$(BIN)/pip install --quiet --no-deps -e .
	touch $(STAMP)

# Refresh the lock to the newest versions pyproject.toml allows (then run `make test` before committing).
lock:
	$(PYTHON) -m venv .lock-venv
	.lock-venv/bin/pip install --quiet uv==$(UV_VERSION)
	.lock-venv/bin/uv pip compile pyproject.toml --extra dev --generate-hashes --python-version 3.11 \
		--python-platform x86_64-manylinux_2_28 -o requirements.lock

venv: $(STAMP)

demo: $(STAMP)
	$(BIN)/drs demo

# Test files run in parallel (pytest-xdist), one file to a worker at a time (--dist loadfile): a file's
# module fixtures are built once and its tests keep their order. --no-loadscope-reorder: the longest files
# start first (tests/conftest.py, LONGEST_FILES), not the files with the most tests, which left the files
# of one long test to one worker at the end. A third of the suite's time waits on real processes (sshd,
# tmux, the simulators), not on a core, so there are more workers than cores. TEST_WORKERS=N overrides.
# 2026-12-04, fresh clones beside two CPU hogs on this 2-core machine, pytest: four workers 12 min 21 s,
# six 10 min 11 s, eight 11 min 15 s (2340 passed each). Quiet, four: 7 min 41 s.
TEST_WORKERS ?= 6
# One thread per worker for numba's parallel kernels and OpenBLAS: the workers already fill both cores,
# and the threads each of them started spun against the other workers' (the pre-flight held-out report:
# 51 s of CPU in the suite, 17 s with one thread).
ONE_THREAD = OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1

# Python's bytecode is cached (__pycache__, ignored by git) even where the shell sets
# PYTHONDONTWRITEBYTECODE, as this machine's does: without the cache every worker rewrote and compiled
# every test file (15.5 s of CPU to collect, 6.8 s with it) and every `drs` process a test starts
# compiled the modules it imports (console.app 1.58 s, 1.41 s with it).
BYTECODE = PYTHONDONTWRITEBYTECODE=

# Beside the lint, the predictor's kernels compile into the checkout's cache (tests/warm_compiled.py),
# not in every worker at once, and one collection writes the bytecode the workers then read (fresh
# clone, quiet: mypy 16 s, the kernels 15 s, the collection 13 s); a failure there is left to the tests.
test: $(STAMP)
	$(BYTECODE) $(BIN)/python -m tests.warm_compiled & \
	$(BYTECODE) $(BIN)/python -m pytest --collect-only -q -p no:cacheprovider >/dev/null & \
	$(BIN)/ruff check . && $(BIN)/ruff format --check . && $(BIN)/lint-imports && $(BIN)/mypy; \
	linted=$$?; wait; [ $$linted -eq 0 ] && \
	$(BYTECODE) $(ONE_THREAD) $(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/lint-imports
	$(BIN)/mypy

bench: $(STAMP)
	$(BIN)/drs predict bench

# The house as docs/architecture.md draws it, made from the code's imports.
house: $(STAMP)
	$(BIN)/python tools/house_diagram.py

bench-console: $(STAMP)
	$(BIN)/python tools/console_latency.py

bench-serve: $(STAMP)
	$(BIN)/python tools/serve_first_answer.py

bench-bytes: $(STAMP)
	$(BIN)/python tools/console_bytes.py

bench-consoles: $(STAMP)
	$(BIN)/python tools/second_console_latency.py

bench-fanout: $(STAMP)
	$(BIN)/python tools/server_fanout.py

bench-telemetry: $(STAMP)
	$(BIN)/python tools/telemetry_fanout.py

screenshots: $(STAMP)
	$(BIN)/python tools/screenshots.py
