# doppler-bench: every target sets up .venv first if needed.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
BENCH := $(VENV)/bin/bench
STAMP := $(VENV)/.installed

.PHONY: install test lint reproduce-table speed clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[dev]"
	touch $(STAMP)

install: $(STAMP)

test: $(STAMP)
	$(PY) -m pytest

lint: $(STAMP)
	$(VENV)/bin/ruff check .

# the paper's Table III on the synthetic suite (or on real stores under data/real when present)
reproduce-table: $(STAMP)
	$(BENCH) reproduce

speed: $(STAMP)
	$(BENCH) speed

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache
