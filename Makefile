# Two commands for a fresh machine: `make demo` and `make test` (see README).
PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
export OMP_NUM_THREADS ?= 1

.PHONY: demo test test-all lint typecheck pytest pytest-all venv browser postgres clean

venv: $(STAMP)

# torch first, pinned: it resolves to the local CPU wheel; the project's own range is then
# already satisfied, so pip never pulls a CUDA build.
# pip byte-compiles on one core; compileall does it on every core (~35 s less of a fresh set-up).
# As pip does, it passes over files it cannot compile (torch ships some for later Pythons).
$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV) || python3 -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet --no-compile torch==2.13.0
	$(BIN)/pip install --quiet --no-compile -e '.[dev]'
	$(BIN)/python -m compileall -q -j 0 $(VENV)/lib > /dev/null || true
	touch $(STAMP)

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

MYPY := $(BIN)/mypy model app

typecheck: $(STAMP)
	$(MYPY)

# Headless Chromium for tests/app/test_browser.py from Debian's packages (once; they skip
# with the reason when it cannot be installed).
browser:
	bash scripts/install-browser.sh

# PostgreSQL 15 from Debian's packages, started, with the tests' login role (idempotent; the
# PostgreSQL tests skip with the reason when it cannot be installed).
postgres:
	bash scripts/install-postgres.sh

# Slow accuracy studies are left out here (pyproject addopts); pytest-all runs every test.
# Tests run on every core, a file to a worker (its module fixtures made once); those marked
# serial (timings, priorities) then run alone, with no neighbour on the machine.
PARALLEL := -n auto --dist loadfile
PARALLEL_TESTS := $(BIN)/pytest -q $(PARALLEL) -m "not slow and not serial"
SERIAL_TESTS := $(BIN)/pytest -q -m "not slow and serial"
pytest: $(STAMP) browser postgres
	$(PARALLEL_TESTS)
	$(SERIAL_TESTS)

pytest-all: $(STAMP) browser postgres
	$(BIN)/pytest -q $(PARALLEL) -m "not serial"
	$(BIN)/pytest -q -m serial

# mypy takes one core for ~1 min from a cold cache: it runs beside the parallel tests, not
# before them; the serial tests then have the machine to themselves.
test: lint $(STAMP) browser postgres
	$(MAKE) --no-print-directory -j 2 mypy-beside parallel-tests
	$(SERIAL_TESTS)

.PHONY: mypy-beside parallel-tests
mypy-beside:
	$(MYPY)
parallel-tests:
	$(PARALLEL_TESTS)

test-all: lint typecheck pytest-all

# The served demo: synthetic thesis fleet (300 aircraft, 15 inspected) in ./fleetpinn.db, one
# retrain, an admin key (printed, and kept in .demo-key for the tour; each run replaces the last
# one), then the API on http://127.0.0.1:$(PORT) (re-running it re-uses the stored records;
# `make demo PORT=8001` where 8000 is taken).
PORT ?= 8000
demo: $(STAMP)
	$(BIN)/fleetpinn migrate
	$(BIN)/fleetpinn seed-demo
	$(BIN)/fleetpinn retrain
	$(BIN)/fleetpinn keys create --role admin --name demo --replace --out .demo-key > /dev/null
	@echo "admin key (also in .demo-key): $$(cat .demo-key)"
	$(BIN)/fleetpinn serve --host 127.0.0.1 --port $(PORT)

clean:
	rm -rf $(VENV) build *.egg-info
