# Each target does its own set-up: a virtual environment with the package (editable)
# and its test and plot dependencies, rebuilt when pyproject.toml changes.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin

.PHONY: setup run test quick lint typecheck generate check bench clean

setup: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test,plot]'
	touch $@

run: setup
	$(BIN)/deltagen validate

# every check of CI: lint, types, generated/ up to date, the test suite
test: lint typecheck
	$(BIN)/deltagen generate --check
	$(BIN)/python -m pytest -q

# the suite without the tests marked slow (sanitizer builds, fresh interpreters)
quick: setup
	$(BIN)/python -m pytest -q -m "not slow"

lint: setup
	$(BIN)/ruff check deltagen tests
	$(BIN)/ruff format --check deltagen tests

typecheck: setup
	$(BIN)/mypy

generate: setup
	$(BIN)/deltagen generate

bench: setup
	$(BIN)/deltagen bench

clean:
	rm -rf $(VENV) build dist *.egg-info validation .pytest_cache .hypothesis .mypy_cache .ruff_cache
