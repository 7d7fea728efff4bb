# doppler-bench: every target sets up .venv first if needed.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
BENCH := $(VENV)/bin/bench
STAMP := $(VENV)/.installed

.PHONY: install system-deps test lint reproduce-table figures speed clean

# Open3D's wheel (the DICP cross-check, an optional extra for users) needs libusb-1.0 from the
# system; install it with apt when it is missing and we may (root), else say what to run.
system-deps:
	@if ! ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0'; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    echo "installing libusb-1.0-0 (needed by Open3D)"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libusb-1.0-0 >/dev/null; \
	  else \
	    echo "note: libusb-1.0 is missing; Open3D (DICP cross-check) needs it: sudo apt-get install libusb-1.0-0"; \
	  fi; \
	fi

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[dev]"
	touch $(STAMP)

install: system-deps $(STAMP)

test: system-deps $(STAMP)
	$(PY) -m pytest

lint: $(STAMP)
	$(VENV)/bin/ruff check .

# the paper's Tables III-V on the synthetic suite (or on real stores under data/real when present)
reproduce-table: system-deps $(STAMP)
	$(BENCH) reproduce

# every paper figure of the reproduced tables (and of `make speed` when it has run)
figures: $(STAMP)
	$(BENCH) figures results/paper-synthetic

speed: $(STAMP)
	$(BENCH) speed

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache
