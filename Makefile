# `make demo` and `make test` each set everything up from nothing, then run.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-$(shell cat pyproject.toml | cksum | cut -d' ' -f1)

.PHONY: demo test lint bench bench-peers bench-ik clean

$(BIN)/python:
	@$(PYTHON) -c 'import venv, ensurepip' 2>/dev/null || { \
	  echo "python3-venv is missing; installing it (needs root)"; \
	  apt-get update -qq && apt-get install -y -qq python3-venv python3-pip; }
	$(PYTHON) -m venv $(VENV)

$(STAMP): $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[dev]'
	@rm -f $(VENV)/.installed-*; touch $@

demo: $(STAMP)
	$(BIN)/busarm demo

test: $(STAMP)
	$(BIN)/ruff check src tests bench
	$(BIN)/mypy
	$(BIN)/python -m pytest -q

lint: $(STAMP)
	$(BIN)/ruff check src tests bench
	$(BIN)/mypy

bench: $(STAMP)
	$(BIN)/busarm bench

# Peers (pylx16a, lewansoul-lx16a) are installed only here, for the side-by-side run.
bench-peers: $(STAMP)
	$(BIN)/python -m pip install -q -e '.[peers]'
	$(BIN)/python bench/peers.py

# IK peers (roboticstoolbox-python, ikpy) are installed only here, for `busarm bench ik --peers`.
bench-ik: $(STAMP)
	$(BIN)/python -m pip install -q -e '.[ikbench]'
	$(BIN)/busarm bench ik --peers

clean:
	rm -rf $(VENV) build *.egg-info src/*.egg-info .pytest_cache .mypy_cache .ruff_cache .hypothesis
