# parkfleet developer commands. `make test` and `make demo` work from a fresh clone.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: install test test-fast docs lint typecheck pytest demo reproduce bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test]'
	touch $(STAMP)

install: $(STAMP)  ## create .venv and install parkfleet with its test extras

lint: $(STAMP)  ## ruff lint + format check + the layer contracts (import-linter)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/lint-imports

typecheck: $(STAMP)  ## mypy --strict on all four packages
	$(BIN)/mypy --strict fleet robot_agent sim_agent api

pytest: $(STAMP)
	$(BIN)/pytest -q

test: lint typecheck pytest  ## everything CI runs

test-fast: $(STAMP)  ## the inner loop: unit tests only (no integration), no lint
	$(BIN)/pytest -q -m "not integration"

docs: $(STAMP)  ## the documentation site (docs/, mkdocs-material) into site/; warnings fail
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --quiet

demo: $(STAMP)  ## the main job
	$(BIN)/parkfleet demo

reproduce: $(STAMP)
	$(BIN)/parkfleet reproduce

bench: $(STAMP)  ## every benchmark (numbers and ratios, no pass/fail)
	$(BIN)/parkfleet bench sim
	$(BIN)/parkfleet bench zenoh
	$(BIN)/parkfleet bench api
	$(BIN)/parkfleet bench fleet

clean:
	rm -rf $(VENV) .mypy_cache .pytest_cache .ruff_cache build *.egg-info
