# Two entry points for a fresh clone: `make demo` (set up, then simulate all five activities) and
# `make test` (set up, then run the test suite). Set-up is idempotent and only redone when pyproject changes.
PYTHON ?= python3.11
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
OUT    ?= out/demo
ACTIVITIES := walk fall sit stand pick

.PHONY: demo test lint env llvm bench docs wheel-check clean

demo: env
	@for a in $(ACTIVITIES); do \
	  $(BIN)/rtchannel simulate --activity $$a --backend points --out $(OUT)/$$a || exit 1; \
	done
	@echo "signatures and plots are in $(OUT)/<activity>/"

# every test, in two processes (pytest-xdist, one per core; a file's tests stay in one process so that its
# fixtures are made once); `-m "not slow"` for a quick run while working
test: env
	$(BIN)/python -m pytest -q -n 2 --dist loadfile

# the static-analysis gate (CI runs it before the tests): ruff over the tree, mypy on rtchannel/ and processing/;
# rules and strictness in pyproject.toml ([tool.ruff], [tool.mypy])
lint: env
	$(BIN)/ruff check .
	$(BIN)/mypy

bench: env
	$(BIN)/python benchmarks/bench_points.py

# API reference (pdoc) into docs/api/ (not committed; CI builds it so a broken docstring or import shows)
docs: env
	$(BIN)/pdoc -o docs/api rtchannel processing

# a regular (non-editable) install into a fresh venv, run from an empty folder
wheel-check: llvm
	PYTHON=$(PYTHON) bash scripts/check_wheel.sh

env: llvm $(STAMP)

# Dr.Jit (Mitsuba/Sionna RT) needs libLLVM >= 16; Debian 12's default 15 aborts the process.
llvm:
	@if ! $(PYTHON) -c "import sys; sys.path.insert(0, '.'); from rtchannel.scene.llvm import find_libllvm; sys.exit(find_libllvm() is None)"; then \
	  if [ "$$(id -u)" = "0" ] && command -v apt-get >/dev/null; then \
	    echo "installing libllvm19 (Dr.Jit needs LLVM >= 16)"; \
	    apt-get update -qq && apt-get install -y -qq libllvm19 >/dev/null; \
	  else \
	    echo "error: no usable libLLVM (>= 16) for Dr.Jit: install LLVM >= 16, e.g. 'sudo apt-get install -y libllvm19'" >&2; exit 2; \
	  fi; \
	fi

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	# torch first, pinned: later requirements must never pull another (CUDA) build
	$(BIN)/pip install -q torch==2.13.0
	$(BIN)/pip install -q -e ".[test]"
	touch $(STAMP)

clean:
	rm -rf $(VENV) out .mypy_cache .ruff_cache
