# psns-hil -- the two commands that matter: `make run` and `make test`.
# Works on a fresh machine with Python 3.11 to 3.13, gcc and make: everything else is installed
# into .venv by `make install` (idempotent: a no-op when pyproject.toml has not changed).

PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-stamp
SCENARIO ?= scenarios/quickstart.yaml

.PHONY: install geoid-grid run examples test test-py print-test-pythons test-slow docs test-realtime test-all fuzz lint bench bench-quick golden compiled test-compiled clean distclean check-python

check-python:
	@$(PYTHON) -c 'import sys; sys.exit(0 if (3, 11) <= sys.version_info[:2] <= (3, 13) else "psns-hil needs Python 3.11 to 3.13 (requires-python in pyproject.toml), found " + sys.version.split()[0])'

$(STAMP): pyproject.toml | check-python
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test,dev,docs]'
	@touch $(STAMP)

install: $(STAMP) geoid-grid

# The emulated GNSS receiver reports EGM96's geoid separation from PROJ's 15' grid (Debian proj-data,
# docs/sensors.md): installed here when missing and we are root with apt-get, otherwise a one-line notice
# (a scenario that needs it then stops with a ScenarioError naming the package).
EGM96_GTX := /usr/share/proj/egm96_15.gtx
geoid-grid:
	@if [ ! -f $(EGM96_GTX) ] && [ ! -f /usr/local/share/proj/egm96_15.gtx ]; then \
	  if [ "$$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then \
	    echo "install: proj-data (EGM96 geoid grid) from Debian"; \
	    apt-get install -y -qq proj-data >/dev/null 2>&1 || (apt-get update -qq >/dev/null 2>&1 && apt-get install -y -qq proj-data >/dev/null 2>&1) \
	      || echo "install: proj-data could not be installed: set sensors.gnss.geoid_sep_m in scenarios or install it"; \
	  else echo "install: $(EGM96_GTX) missing: 'sudo apt-get install proj-data' (or set sensors.gnss.geoid_sep_m)"; fi; \
	fi

run: install
	$(VENV)/bin/psns-hil run $(SCENARIO)

# The example foreign firmware in C (examples/c_firmware, docs/runtime.md section DSP out); its test builds it too.
examples:
	@if command -v $${CC:-gcc} >/dev/null 2>&1; then $(MAKE) -C examples/c_firmware; \
	else echo "examples: no C compiler (gcc): examples/c_firmware not built, its test will be skipped"; fi

# The suite under coverage, started before anything imports the package (pytest loads the package's own plugin
# before `--cov` could start it), child processes included ([tool.coverage.run] in pyproject.toml), over
# TEST_WORKERS pytest-xdist worker processes (docs/decisions/emulator-runtime.md D-7.31): each worker is a child
# process, measured from its first line like any other, and `coverage combine` joins their data files. The floor is
# the measured figure of the pure-Python tree minus at most one point (README.md): raise it when the figure rises.
# Measured 2026-12-07 on the full suite (fresh clone, 2 xdist workers): 88.5 % (statements and branches; README.md).
COVERAGE_FLOOR := 87.5
#: pytest-xdist worker processes of `make test` and `make test-py` (the CI machine has 2 cores; 1 = one process)
TEST_WORKERS ?= 2
#: --dist loadscope keeps a module's tests on one worker, so its module-scoped fixtures (runs, clusters) run once
XDIST := -n $(TEST_WORKERS) --dist loadscope
test: install examples
	$(PY) -m coverage erase
	$(PY) -m coverage run -m pytest $(XDIST)
	$(PY) -m coverage combine --quiet
	$(PY) -m coverage report --skip-covered --fail-under=$(COVERAGE_FLOOR)

# The linters and the suite on another Python (issue 42 item 8; .ci/run runs it for each of TEST_PYTHONS):
# `make test-py PYV=3.12`. Its own venv, .venv-3.12, installed like .venv (again when pyproject.toml changes); the
# interpreter from tools/python_for.sh (PATH, then pyenv, else pyenv builds it, else it says how to get one and
# fails). No coverage: the figure is .venv's (README.md); the same tests, the same markers, over TEST_WORKERS.
TEST_PYTHONS := 3.12 3.13
PYV ?=
print-test-pythons:
	@echo $(TEST_PYTHONS)
test-py: examples geoid-grid
	@test -n "$(PYV)" || { echo "test-py: say which Python, e.g. make test-py PYV=3.12"; exit 2; }
	@v=.venv-$(PYV); if [ ! -f $$v/.installed-stamp ] || [ pyproject.toml -nt $$v/.installed-stamp ]; then \
	  interp=$$(tools/python_for.sh $(PYV)) || exit 2; echo "test-py: $$v from $$interp"; \
	  $$interp -m venv $$v && $$v/bin/python -m pip install --quiet --upgrade pip && \
	  $$v/bin/python -m pip install --quiet -e '.[test,dev]' && touch $$v/.installed-stamp; fi
	.venv-$(PYV)/bin/ruff check .
	.venv-$(PYV)/bin/mypy --python-version $(PYV)
	.venv-$(PYV)/bin/lint-imports
	.venv-$(PYV)/bin/python -m pytest -p no:cacheprovider $(XDIST)

# Tests that follow the wall clock (ptys, sockets, other processes): their own step in .ci/run.
test-realtime: install examples
	$(PY) -m pytest -m realtime

# The tests marked slow (long runs: full library replays, campaigns, hour-long scenarios), not in `make test`:
# the opt-in step of .ci/run (CI_SLOW=1 .ci/run), over TEST_WORKERS like `make test`, without coverage.
test-slow: install examples
	$(PY) -m pytest -p no:cacheprovider -m slow $(XDIST)

# Everything: the suite, the slow and the wall-clock tests, in one process (the wall-clock tests share no core).
test-all: install examples
	$(PY) -m pytest -m ''

# Long seeded fuzz of every decoder (byte mutations and hostile field tokens) and of the firmware's input path,
# over three seeds (>= 3.3 x 10^6 cases; not in `make test`, whose tests/fuzz runs a short version):
# prints the case counts, exits 1 on any exception, stuck decoder or non-finite state (docs/hostile-input.md).
FUZZ_ARGS ?=
fuzz: install
	$(PY) -m tests.fuzz.fuzz_inputs --seeds 3 $(FUZZ_ARGS)

# The API reference from the docstrings (Sphinx: docs/conf.py, docs/api/; docs/decisions/emulator-runtime.md D-7.20):
# HTML in build/docs (git-ignored; open build/docs/index.html). Every warning fails the build, here as in .ci/run.
# The per-module pages are generated afresh each time (docs/api/generated, git-ignored), so a moved module leaves
# no stale page behind.
docs: install
	rm -rf docs/api/generated
	$(VENV)/bin/sphinx-build -q -W --keep-going -c docs docs/api build/docs

# The linters .ci/run runs before the tests: style and errors, types, layers.
lint: install
	$(VENV)/bin/ruff check .
	$(VENV)/bin/mypy
	$(VENV)/bin/lint-imports

# The full table (10 min realtime pty run, twice as root: 5.10; 1/10/60 min scaling): about 35 minutes.
bench: install
	$(PY) -m benchmarks

# The same table with every long item shortened (docs/performance.md): a few minutes.
bench-quick: install
	PSNS_BENCH_QUICK=1 $(PY) -m benchmarks

# Regenerate the change-indicator records of the scenario library (tests/golden/); review and commit the diff.
golden: install
	$(PY) -m emulator golden --update

# Opt-in compiled path (docs/performance.md section 5.5, D-10.F3): mypyc compiles the modules listed in
# pyproject.toml [tool.psns-hil.compiled] from their one Python source (gcc, Python headers) and places the
# extensions beside the sources, where the same imports pick them up. `make clean` goes back to pure Python,
# the default and what CI tests; `tools/build_compiled.py --files` says which path a tree is on.
compiled: install
	$(PY) tools/build_compiled.py

# The compiled path as CI checks it (its last step, D-10.F4): build it, run the tests that compare it with the
# pure-Python sources and the tests of the compiled modules against it, then remove it whatever the outcome, so
# the tree is pure Python again. A few minutes.
COMPILED_TESTS := tests/tools/test_build_compiled.py tests/test_fast_paths.py tests/emulator/test_numeric_baseline.py \
	tests/firmware_model/test_strapdown.py tests/firmware_model/test_hostile_input.py tests/protocols/test_crc.py \
	tests/emulator/recording/test_nav_error.py tests/emulator/postrun/test_golden.py \
	tests/emulator/links/test_links_mem.py tests/emulator/links/test_framing.py \
	tests/emulator/devices/test_imu.py tests/emulator/devices/test_imu_lookahead.py \
	tests/emulator/devices/test_imu_temperature.py tests/emulator/devices/test_field_models.py
test-compiled: compiled
	$(PY) -m pytest -p no:cacheprovider $(COMPILED_TESTS); rc=$$?; $(PY) tools/build_compiled.py --clean; exit $$rc

clean:
	$(PYTHON) tools/build_compiled.py --clean
	rm -rf runs .pytest_cache .hypothesis
	find . -name __pycache__ -type d -prune -exec rm -rf {} +

distclean: clean
	rm -rf $(VENV) *.egg-info
