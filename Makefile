# Two commands set everything up on a fresh machine with Python 3.11+:
#   make demo   creates .venv, installs nupatch, builds a shipped model to STEP and checks it
#   make test   creates or updates .venv and runs the whole test suite
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
# test workers (pytest-xdist): one per core; `make test JOBS=0` runs in one process
JOBS ?= auto
STAMP := $(VENV)/.nupatch-installed
DEMO_MODEL ?= models/l_bracket.obj
DEMO_OUT ?= build/l_bracket.step

.PHONY: demo test env clean

env: $(STAMP)

$(STAMP): pyproject.toml requirements/environment.txt requirements/no-deps.txt
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -r requirements/environment.txt
	$(BIN)/python -m pip install -q --no-deps -r requirements/no-deps.txt
	$(BIN)/python -m pip install -q --no-deps -e .
	touch $(STAMP)

demo: $(STAMP)
	mkdir -p build
	$(BIN)/nupatch build $(DEMO_MODEL) -o $(DEMO_OUT)
	$(BIN)/nupatch check $(DEMO_OUT)

test: $(STAMP)
	$(BIN)/python -m pytest -q -n $(JOBS) --dist worksteal

clean:
	rm -rf build .pytest_cache
