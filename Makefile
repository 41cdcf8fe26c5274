# dgt-kit: two commands do all set-up.
#   make reproduce   run the whole pipeline (DGT_PROFILE, default demo)
#   make test        unit tests + every notebook under nbmake (smoke profile)
#   make figures     the README's figures from the demo run (docs/figures/)
#   make docs        the result tables of the README, docs and notebooks from the committed run records
SHELL := /bin/bash
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
PROFILE ?= $(or $(DGT_PROFILE),demo)
STAMP := $(VENV)/.installed

.PHONY: reproduce test lint figures docs venv clean-data

venv: $(STAMP)

# The venv is (re)built when pyproject.toml changes. Without CUDA we install the
# CPU torch wheel first (torch==2.13.0), so the range in pyproject is already
# satisfied and pip never downloads a multi-GB CUDA build.
$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	@if command -v nvidia-smi >/dev/null 2>&1 && nvidia-smi -L >/dev/null 2>&1; then \
	    echo "CUDA GPU found: installing the default torch build"; \
	    $(PY) -m pip install -q torch; \
	else \
	    echo "no CUDA GPU: installing the CPU torch build (torch==2.13.0)"; \
	    { $(PY) -m pip install -q --no-index --no-deps torch==2.13.0 2>/dev/null \
	      && $(PY) -m pip install -q torch==2.13.0; } \
	    || $(PY) -m pip install -q torch==2.13.0 --index-url https://download.pytorch.org/whl/cpu; \
	fi
	$(PY) -m pip install -q -e '.[dev]'
	@touch $(STAMP)

reproduce: $(STAMP)
	MUJOCO_GL=egl $(VENV)/bin/dgt reproduce --profile $(PROFILE)

# CI runs exactly this. The smoke pipeline runs once (it is the main job's code path,
# and it warms the artifact cache), then every notebook runs on that cache under nbmake.
# One BLAS/torch thread per process: two pytest workers already fill two cores.
SMOKE := DGT_PROFILE=smoke MUJOCO_GL=egl OMP_NUM_THREADS=1
test: $(STAMP)
	$(SMOKE) $(PY) -m pytest -n 2 --dist loadfile tests
	$(SMOKE) $(VENV)/bin/dgt reproduce --profile smoke
	$(SMOKE) $(PY) -m pytest -n 2 --dist loadfile --nbmake --nbmake-timeout=900 notebooks

# The README's figures (docs/figures/*.png) from the demo run's seed 0: its cached
# artifacts are read, missing ones built as `make reproduce` would.
figures: $(STAMP)
	MUJOCO_GL=egl $(PY) -m dgt_lib.app.figures --profile demo

# Every generated block of README.md and docs/ from the run records in docs/runs/ (the runs
# named in docs/runs/cited.json). Publish a run first: python -m dgt_lib.records publish.
docs: $(STAMP)
	$(PY) -m dgt_lib.records render

lint: $(STAMP)
	$(VENV)/bin/ruff check dgt_lib tests benchmarks studies examples

clean-data:
	rm -rf data/smoke data/demo data/paper
