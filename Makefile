# `make demo` and `make test` each set everything up from nothing, then run.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-$(shell cat pyproject.toml | cksum | cut -d' ' -f1)

.PHONY: demo test tests-and-types test-fast lint docs bench bench-peers bench-ik profile-pick gl browser lerobot clean

$(BIN)/python:
	@$(PYTHON) -c 'import venv, ensurepip' 2>/dev/null || { \
	  echo "python3-venv is missing; installing it (needs root)"; \
	  apt-get update -qq && apt-get install -y -qq python3-venv python3-pip; }
	$(PYTHON) -m venv $(VENV)

$(STAMP): $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[dev]'
	@rm -f $(VENV)/.installed-*; touch $@

# LeRobot (and a CPU build of PyTorch) live in an environment of their own, with busarm and
# its LeRobot plugin (integrations/lerobot; docs/lerobot.md says why these versions).
LEROBOT_VENV  := .venv-lerobot
LEROBOT_FILES := pyproject.toml integrations/lerobot/pyproject.toml $(wildcard integrations/lerobot/venv/*)
LEROBOT_STAMP := $(LEROBOT_VENV)/.installed-$(shell cat $(LEROBOT_FILES) | cksum | cut -d' ' -f1)

$(LEROBOT_STAMP): $(LEROBOT_FILES)
	integrations/lerobot/venv/install.sh $(LEROBOT_VENV) $(PYTHON)
	@rm -f $(LEROBOT_VENV)/.installed-*; touch $@

lerobot: $(LEROBOT_STAMP)

# The twin renders its cameras offscreen with Mesa's EGL on the CPU; install it when it
# is missing and we are root, else say what to install.
GL_OK := $(shell ldconfig -p 2>/dev/null | grep -q 'libEGL_mesa.so' && echo yes)
gl:
ifneq ($(GL_OK),yes)
	@if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	  echo "installing Mesa EGL (offscreen OpenGL) for the twin's cameras"; \
	  apt-get update -qq && apt-get install -y -qq libegl1 libegl-mesa0 libgl1-mesa-dri >/dev/null; \
	else \
	  echo "the twin's cameras need Mesa EGL: sudo apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri" >&2; \
	  exit 1; \
	fi
endif

# The dashboard's browser tests (tests/browser) drive Debian's chromium through Playwright;
# install it when it is missing and we are root, else say what to install. (Never
# `playwright install`: it downloads a browser build of its own.)
browser:
	@if [ ! -x /usr/bin/chromium ]; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    echo "installing chromium for the dashboard's browser tests"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; \
	  else \
	    echo "the dashboard's browser tests need chromium: sudo apt-get install chromium" >&2; \
	    exit 1; \
	  fi; \
	fi

# The main job on the twin: calibrate its camera, then sort a seeded table of 5 blocks.
demo: $(STAMP) gl
	$(BIN)/busarm pick-sort --seed 3 --blocks 5 --report demo-report

# lint-imports checks the layer contract in pyproject.toml ([tool.importlinter]); --no-cache:
# the graph takes well under a second, and no .import_linter_cache/ is left in the tree.
# The tests start some hundreds of busarm processes: their bytecode is cached (in
# .venv/pycache, not in the tree) even where PYTHONDONTWRITEBYTECODE is set, else each
# process compiles busarm's modules again (0.2 s a command).
# The suite runs in TEST_WORKERS processes (pytest-xdist), all of it in one pass: the
# simulations run on their simulated clocks, and the tests on the wall clock (marked
# `wallclock`) are written for a busy computer. The slow tests are collected first
# (tests/conftest.py) and an idle worker takes over half of another's queue (worksteal),
# so the long jobs start early and neither worker ends alone. mypy (under a minute of one
# core on a fresh clone) runs beside the tests, and its verdict counts as theirs does.
# Exit code 5 is "no test selected" (PYTEST_ARGS picked none).
# Three workers on two cores: a third of the suite's time is spent waiting on the wall
# clock (ptys, servers, a browser), which a third worker fills; beside other busy programs
# it also keeps the suite's share of the cores (docs/benchmarks.md: 9-11 min there with
# three, 12 min 15 s - 12 min 40 s with two; alone 5 min 54 s with three, 6 min 43 s with two).
TEST_WORKERS ?= 3
PYTEST := env -u PYTHONDONTWRITEBYTECODE PYTHONPYCACHEPREFIX=$(CURDIR)/$(VENV)/pycache \
	  $(BIN)/python -m pytest -q
define TESTS_AND_TYPES
	@$(BIN)/mypy > $(VENV)/mypy.log 2>&1 & types=$$!; \
	$(PYTEST) -n $(TEST_WORKERS) --dist worksteal $(1) $(PYTEST_ARGS); tests=$$?; [ $$tests = 5 ] && tests=0; \
	wait $$types; typed=$$?; cat $(VENV)/mypy.log; \
	[ $$tests = 0 ] && [ $$typed = 0 ]
endef
# The LeRobot tests (tests/with_lerobot) run in LeRobot's environment, beside the rest:
# its install (a minute and a half, mostly unpacking) and then its tests go on in the
# background while the main suite runs, and their verdict counts as the suite's does.
LEROBOT_PYTEST := env -u PYTHONDONTWRITEBYTECODE \
	  PYTHONPYCACHEPREFIX=$(CURDIR)/$(LEROBOT_VENV)/pycache $(LEROBOT_VENV)/bin/python -m pytest -q
test: $(STAMP) gl browser
	$(BIN)/ruff check src tests integrations
	$(BIN)/lint-imports --no-cache
	@mkdir -p build; ( $(MAKE) -s lerobot > build/lerobot-install.log 2>&1 \
	  || { echo "make lerobot failed: build/lerobot-install.log"; tail -n 20 build/lerobot-install.log; exit 1; }; \
	  $(LEROBOT_PYTEST) -n 2 tests/with_lerobot $(PYTEST_ARGS) ) > build/lerobot-tests.log 2>&1 & lerobot=$$!; \
	$(MAKE) -s tests-and-types; main=$$?; \
	wait $$lerobot; learned=$$?; echo "LeRobot tests (.venv-lerobot):"; cat build/lerobot-tests.log; \
	[ $$main = 0 ] && [ $$learned = 0 ]

tests-and-types: $(STAMP)
	$(call TESTS_AND_TYPES,--ignore=tests/with_lerobot)

# The inner loop: everything but the tests marked slow (the README's blocks, whole jobs
# on the twin, the browser): under 2 minutes on two cores. `make test` runs them all.
test-fast: $(STAMP) gl
	$(BIN)/ruff check src tests integrations
	$(BIN)/lint-imports --no-cache
	$(call TESTS_AND_TYPES,--ignore=tests/with_lerobot -m "not slow and not wallclock")

# The API reference, from the docstrings, to build/api/ (open build/api/index.html); a
# warning is an error. tests/unit/test_api_reference.py builds it in `make test` too.
docs: $(STAMP)
	$(BIN)/python docs/api_reference.py build/api

lint: $(STAMP)
	$(BIN)/ruff check src tests
	$(BIN)/mypy
	$(BIN)/lint-imports --no-cache

bench: $(STAMP)
	$(BIN)/busarm bench

# Peers (pylx16a, lewansoul-lx16a) are installed only here, for the side-by-side run.
bench-peers: $(STAMP)
	$(BIN)/python -m pip install -q -e '.[peers]'
	$(BIN)/python -m busarm.bench.peers

# Where the pick bench's time goes, sampled by py-spy (installed only here): a flame graph
# to build/pick-bench.svg (docs/profiles/pick-bench.md).
profile-pick: $(STAMP) gl
	$(BIN)/python -m pip install -q -e '.[profile]'
	@mkdir -p build
	$(BIN)/py-spy record -r 250 -f flamegraph -o build/pick-bench.svg -- \
	  $(BIN)/busarm bench pick --scenes 6 --seed 7100

# IK peers (roboticstoolbox-python, ikpy) are installed only here, for `busarm bench ik --peers`.
bench-ik: $(STAMP)
	$(BIN)/python -m pip install -q -e '.[ikbench]'
	$(BIN)/busarm bench ik --peers

clean:
	rm -rf $(VENV) $(LEROBOT_VENV) build *.egg-info src/*.egg-info .pytest_cache .mypy_cache .ruff_cache .hypothesis
