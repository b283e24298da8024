# Quick start on a fresh machine with python3:  make demo   |   make test
# Each target creates .venv if missing and installs qfg (editable) with what it needs.
# Outputs go under out/; only the *-update targets rewrite tracked files.

PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.qfg-installed

.PHONY: demo test lint docs bench bench-update clean

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --upgrade pip
	$(BIN)/python -m pip install -e ".[test,dask,docs]"
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/qfg demo

test: $(STAMP)
	$(BIN)/python -m pytest

lint: $(STAMP)
	$(BIN)/ruff check .

# the API reference, generated from the docstrings (docs/api/conf.py), into out/docs; built from
# a copy of docs/api so that autosummary's generated stubs stay out of the checkout
docs: $(STAMP)
	rm -rf out/docs-src out/docs && mkdir -p out && cp -r docs/api out/docs-src
	$(BIN)/python -m sphinx -b html -q out/docs-src out/docs
	@echo "API reference: out/docs/index.html"

# results and their page in out/benchmarks; the tracked record is left alone
bench: $(STAMP)
	$(BIN)/python -m benchmarks --output out/benchmarks

# the same, recorded: benchmarks/results/*.json and docs/benchmarks.md rewritten
bench-update: $(STAMP)
	$(BIN)/python -m benchmarks --update

clean:
	rm -rf $(VENV) out .pytest_cache .ruff_cache build
