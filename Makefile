# The two commands of the README: `make demo` (main job) and `make test` (test suite).
# Each sets up a local .venv with the pinned versions of requirements.lock, idempotently.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test setup clean-venv

setup: $(STAMP)

$(STAMP): requirements.lock setup.cfg pyproject.toml
	@bash .ci/system-deps
	@test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -r requirements.lock
	$(BIN)/python -m pip install --quiet --no-deps --no-build-isolation -e .
	@touch $(STAMP)

demo: $(STAMP)
	$(BIN)/ancsh demo

test: $(STAMP)
	$(BIN)/python -m pytest -q tests $(PYTEST_ARGS)

clean-venv:
	rm -rf $(VENV)
