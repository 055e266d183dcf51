# snapwarn — one entry point for people and CI.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
PYTEST_ARGS ?=

.PHONY: setup demo test test-slow lint bench serve openapi fuzz clean clean-kernels

# Create the virtual environment with the project (editable) and its dev tools, only when
# missing or when pyproject.toml changed since the last install.
$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[dev]'
	touch $(STAMP)

## numba's kernels compiled once, here, not at first use: the warm-up runs every public path
## on tiny inputs and numba caches what it compiles (__pycache__ next to the sources). Run again
## whenever the numerics' sources change. numba keys a kernel's cache by its own file only, so
## a kernel calling a changed kernel of another module would keep a stale copy: when a file
## that defines kernels changed, every cached kernel is dropped first and compiled again.
KSTAMP     := $(VENV)/.kernels-stamp
KERNEL_SRC := $(shell find sim service/analysis -name '*.py' 2>/dev/null) service/warmup.py

$(KSTAMP): $(STAMP) $(KERNEL_SRC)
	@if [ -f $(KSTAMP) ] && [ -n "$$(find sim service/analysis -name '*.py' -newer $(KSTAMP) \
	    | xargs -r grep -l '@njit')" ]; then \
	  echo "kernel sources changed: dropping numba's cache"; $(MAKE) --no-print-directory clean-kernels; fi
	@echo "numba kernels: compiling what the cache lacks (a few minutes on a fresh install)"
	$(BIN)/python -m service.warmup || echo "WARNING: the kernel warm-up failed on a path (above): those kernels compile at first use"
	@touch $(KSTAMP)

## Python's bytecode, written once here too: an editable install compiles none, and where
## PYTHONDONTWRITEBYTECODE is set every command would compile the project's modules from source
## again (~0.05-0.1 s CPU of a `snapwarn detect`). Only the stale files are compiled.
setup: $(STAMP) $(KSTAMP)
	@$(BIN)/python -m compileall -q -j 0 service sim > /dev/null

## The main job on embedded defaults.
demo: setup
	$(BIN)/snapwarn demo $(DEMO_ARGS)

## The default test suite (slow suites excluded; CI runs them with `make test-slow`).
test: setup
	$(BIN)/python -m pytest -m "not slow" $(PYTEST_ARGS)

test-slow: setup
	$(BIN)/python -m pytest -m slow --durations=30 $(PYTEST_ARGS) || [ $$? -eq 5 ]

lint: setup
	$(BIN)/ruff check sim service tests bench

serve: setup
	$(BIN)/snapwarn serve

## Every benchmark (one command each; BENCH_ARGS=--quick for a smoke run).
bench: setup
	$(BIN)/python bench/beam.py $(BENCH_ARGS)
	$(BIN)/python bench/detector.py $(BENCH_ARGS)
	$(BIN)/python bench/cosserat.py $(BENCH_ARGS)
	$(BIN)/python bench/warn.py $(BENCH_ARGS)
	$(BIN)/python bench/service.py

## Schemathesis against a real server on loopback (SQLite; FUZZ_DB=<postgresql URL> for another).
FUZZ_DB ?= sqlite
fuzz: setup
	$(BIN)/python tests/service/_svc_fuzz.py --db "$(FUZZ_DB)"

## Export the OpenAPI spec of the real app to openapi/openapi.json.
openapi: setup
	$(BIN)/snapwarn openapi

clean: clean-kernels
	rm -rf $(VENV) .pytest_cache build *.egg-info

## numba's compiled kernels: a kernel's cache is not refreshed when a kernel it calls, in
## another module, changes (`make setup` does this itself when a kernel file changed).
clean-kernels:
	find sim service -name '*.nbi' -delete -o -name '*.nbc' -delete
	rm -f $(KSTAMP)
