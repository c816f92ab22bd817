# Each target does its own set-up: a virtual environment with the package (editable)
# and its test dependencies, rebuilt when pyproject.toml changes.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin

.PHONY: setup run test generate check bench clean

setup: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $@

run: setup
	$(BIN)/deltagen validate

test: setup
	$(BIN)/deltagen generate --check
	$(BIN)/python -m pytest -q

generate: setup
	$(BIN)/deltagen generate

bench: setup
	$(BIN)/deltagen bench

clean:
	rm -rf $(VENV) build dist *.egg-info validation .pytest_cache .hypothesis
