# Each target does its own set-up: a virtual environment with the package (editable)
# and its test, plot and design dependencies, rebuilt when pyproject.toml changes.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
# pytest workers: the cores this process may use, at most 4 (each worker compiles C)
JOBS ?= $(shell $(PYTHON) -c "import os; print(min(4, len(os.sched_getaffinity(0))) if hasattr(os, 'sched_getaffinity') else 2)")
PYTEST := $(BIN)/python -m pytest -q -n $(JOBS) --dist loadfile

.PHONY: setup sysdeps run test quick lint typecheck generate check bench clean

setup: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test,plot,design]'
	touch $@

# System tools some tests use, from Debian's packages where apt works (CI runs as root):
# Chromium for the 3D workspace page, clang and arm-none-eabi-gcc for the exported C package,
# valgrind (callgrind and valgrind/callgrind.h) for the instruction counts of the kernels.
# Elsewhere nothing is installed and those tests skip, naming what is missing.
SYSDEPS := chromium clang gcc-arm-none-eabi libnewlib-arm-none-eabi valgrind
sysdeps:
	@if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	  missing=""; for p in $(SYSDEPS); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	  if [ -n "$$missing" ]; then echo "apt-get install$$missing"; \
	    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing >/dev/null) \
	    || echo "sysdeps: apt-get failed; the tests that need$$missing will skip"; fi; \
	else echo "sysdeps: not root or no apt-get; tests needing $(SYSDEPS) skip where absent"; fi

run: setup
	$(BIN)/deltagen validate

# every check of CI: lint, types, the test suite (generated/ up to date is checked module by
# module inside it, in parallel: tests/codegen/test_generated_*.py, as `deltagen generate
# --check` does; `pytest --update-generated` rewrites)
test: sysdeps lint typecheck
	$(PYTEST)

# the suite without the tests marked slow (sanitizer builds, fresh interpreters)
quick: setup
	$(PYTEST) -m "not slow"

lint: setup
	$(BIN)/ruff check deltagen tests
	$(BIN)/ruff format --check deltagen tests

typecheck: setup
	$(BIN)/mypy

generate: setup
	$(BIN)/deltagen generate

bench: setup
	$(BIN)/python -m pip install --quiet -e '.[test,plot,bench]'
	$(BIN)/deltagen bench --markdown --json bench.json --png bench.png

clean:
	rm -rf $(VENV) build dist *.egg-info validation .pytest_cache .hypothesis .mypy_cache .ruff_cache
