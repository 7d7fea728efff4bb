# doppler-bench: every target sets up .venv first if needed.
# Installs are pinned by the lock files in requirements/ (pip constraints, made by `make lock`):
# runtime.txt for the package, dev.txt for the package with its dev extras (the same pins plus
# the dev tools). `make reproduce-table` installs the runtime only; `make test` adds the dev
# extras. A stamp per install records what the venv has, so neither reinstalls needlessly.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
BENCH := $(VENV)/bin/bench
RUNTIME_LOCK := requirements/runtime.txt
DEV_LOCK := requirements/dev.txt
RUNTIME_STAMP := $(VENV)/.installed-runtime
DEV_STAMP := $(VENV)/.installed-dev
PIP_TOOLS := pip-tools==7.6.2
LOCK_VENV := .venv-lock

.PHONY: install install-dev system-deps test fuzz lint docs reproduce-table figures speed lock \
	clean mutate

# System packages the tests need, installed with apt when missing and we may (root), else we
# say what to run: libusb-1.0 for Open3D's wheel (a dev extra: the DICP cross-check) and
# Debian's chromium, in which the HTML report test opens `bench report`'s page (that test
# fails without it).
APT_INSTALL := apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq
system-deps:
	@if ! ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0'; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    echo "installing libusb-1.0-0 (needed by Open3D)"; \
	    $(APT_INSTALL) libusb-1.0-0 >/dev/null; \
	  else \
	    echo "note: libusb-1.0 is missing; Open3D (DICP cross-check) needs it: sudo apt-get install libusb-1.0-0"; \
	  fi; \
	fi
	@if ! command -v chromium >/dev/null && ! command -v chromium-browser >/dev/null; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    echo "installing chromium (the HTML report test opens the page in it)"; \
	    $(APT_INSTALL) chromium >/dev/null; \
	  else \
	    echo "note: chromium is missing; the HTML report test needs it: sudo apt-get install chromium"; \
	  fi; \
	fi

# pip install, quiet; its warning "typer ... does not provide the extra 'all'" is left out:
# it comes from kiss-icp's requirement `typer[all]`, an extra that typer dropped in 0.12 when
# plain typer came to include what it gave (rich, shellingham), so nothing is missing. Any other
# output is shown, and a failing install shows everything and stops. setuptools' block
# "Editable installation ... Please be careful with folders in your working directory" is not
# hidden here but avoided: pyproject.toml names the checkout as the package directory, so the
# editable install is a static .pth entry rather than an import-hook finder.
PIP_LOG := $(VENV)/.pip-install.log
define pip_install
	@echo "pip install $(1)"
	@$(PY) -m pip install --quiet $(1) > $(PIP_LOG) 2>&1 || { cat $(PIP_LOG); exit 1; }
	@grep -v "does not provide the extra 'all'" $(PIP_LOG) || true
endef

$(PY):
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip

# the package and its runtime dependencies, pinned
$(RUNTIME_STAMP): pyproject.toml $(RUNTIME_LOCK) | $(PY)
	$(call pip_install,-c $(RUNTIME_LOCK) -e .)
	touch $@

# the package with its dev extras, pinned (dev.txt holds the runtime pins too, so the runtime
# install is then complete as well)
$(DEV_STAMP): pyproject.toml $(RUNTIME_LOCK) $(DEV_LOCK) | $(PY)
	$(call pip_install,-c $(DEV_LOCK) -e ".[dev]")
	touch $(RUNTIME_STAMP) $@

install: $(RUNTIME_STAMP)

install-dev: system-deps $(DEV_STAMP)

# the suite in one worker per core (pytest-xdist, at most 4: each worker loads numba's kernels,
# compiled once into its cache, and builds the session fixtures once), a test file's tests in
# one worker (--dist loadfile, so its module fixtures are built once); `$(PY) -m pytest
# tests/test_x.py` runs in one process
test: system-deps $(DEV_STAMP)
	$(PY) -m pytest -n auto --maxprocesses 4 --dist loadfile

# the property tests (Hypothesis) with many random examples: `make test` runs them with the
# fast profile (a few fixed examples each), this with the long one (tests/strategies.py)
fuzz: $(DEV_STAMP)
	HYPOTHESIS_PROFILE=long $(PY) -m pytest tests/test_props_cli.py tests/test_props_readers.py \
	  tests/test_options.py

lint: $(DEV_STAMP)
	$(VENV)/bin/ruff check .

# the manual (docs/, mkdocs.yml): regenerate its generated parts (the command reference from the
# command line, the datasets page from the loader table), then build it into site/; --strict
# fails on a broken link or anchor
docs: $(DEV_STAMP)
	$(PY) -m bench.docs_cli
	$(PY) -m bench.data.catalogue
	$(VENV)/bin/mkdocs build --strict

# the paper's Tables III-V on the synthetic suite (or on real stores under data/real when present)
# INTERVALS=1 prints every figure's 95 % interval in the tables' cells (`bench reproduce --ci`,
# as `bench table --ci`); without it the captions name the CSV columns that hold them
INTERVALS ?=
reproduce-table: $(RUNTIME_STAMP)
	$(BENCH) reproduce $(if $(filter 1 yes true,$(INTERVALS)),--ci,)

# every paper figure of the reproduced tables (and of `make speed` when it has run): of the
# folder `make reproduce-table` wrote last (results/paper-real or results/paper-synthetic, by
# its reproduction.json), then its results page
figures: $(RUNTIME_STAMP)
	@dir=$$(ls -t results/paper-real/reproduction.json results/paper-synthetic/reproduction.json \
	        2>/dev/null | head -n 1 | xargs -r dirname); \
	if [ -z "$$dir" ]; then echo "no reproduced tables yet: run make reproduce-table first"; exit 2; fi; \
	echo "figures of $$dir (the last reproduction)"; \
	$(BENCH) figures "$$dir" && $(BENCH) report "$$dir"

speed: $(RUNTIME_STAMP)
	$(BENCH) speed

# mutation testing of what changed since BASE (tools/mutate.py): mutmut mutates the modules of
# bench, loaders, methods, metrics changed since BASE, runs the test files that import them (or
# are named after them) on each mutant, one worker, and lists the survivors; a scratch copy of
# the working tree in .mutate/ (git-ignored) holds its state. ONLY=<paths> narrows the modules,
# ARGS passes more options (--depth 1, --tests ...).
mutate:
	@test -n "$(BASE)" || { echo "usage: make mutate BASE=<commit> [ONLY='metrics/units.py ...']"; exit 2; }
	@$(MAKE) --no-print-directory $(DEV_STAMP)
	@$(PY) -c 'import mutmut' 2>/dev/null || $(PY) -m pip install --quiet 'mutmut>=3.2'
	$(PY) tools/mutate.py --base $(BASE) $(if $(ONLY),--only $(ONLY)) $(ARGS)

# Refresh the lock files with pip-tools (in a venv of its own) for Python 3.11: keeps every pin
# that still satisfies pyproject.toml and resolves what changed; `make lock UPGRADE=1` moves
# every pin to the newest allowed version. The dev lock is constrained by the runtime lock, so
# the two agree on every shared package.
LOCK_FLAGS := --quiet --strip-extras --no-emit-index-url --no-emit-find-links \
	--no-emit-trusted-host $(if $(UPGRADE),--upgrade)
lock:
	@$(PYTHON) -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' || \
	  { echo "make lock: the lock files are for Python 3.11; run PYTHON=python3.11 make lock"; exit 1; }
	test -x $(LOCK_VENV)/bin/pip-compile || \
	  { $(PYTHON) -m venv $(LOCK_VENV) && $(LOCK_VENV)/bin/python -m pip install --quiet "$(PIP_TOOLS)"; }
	CUSTOM_COMPILE_COMMAND="make lock" $(LOCK_VENV)/bin/pip-compile $(LOCK_FLAGS) \
	  -o $(RUNTIME_LOCK) pyproject.toml
	CUSTOM_COMPILE_COMMAND="make lock" $(LOCK_VENV)/bin/pip-compile $(LOCK_FLAGS) \
	  --extra dev -c $(RUNTIME_LOCK) -o $(DEV_LOCK) pyproject.toml

clean:
	rm -rf $(VENV) $(LOCK_VENV) .pytest_cache .ruff_cache site
