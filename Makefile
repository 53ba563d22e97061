# Quick start: `make demo` then `make test`. Both create .venv on first use.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test bench clean figures

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

# The seed paper's Table 2 side by side with ours, then the whole loop on the default
# scene: render, calibrate from the photos, plan, simulate, photograph, measure (~4 min, README).
demo: $(STAMP)
	$(BIN)/vision-cal fixtures/paper_sm5 --method paper --out out/paper_sm5
	$(BIN)/vision-cal loop renders/default.yaml --out out/demo
	@echo "disk used by out/: $$(du -sh out | cut -f1)"
	@echo "vision-cal is installed in $(BIN)/: type '. $(BIN)/activate' to run it as 'vision-cal' in this shell"

# The README's headline table from docs/figures.json, the demo's rows from the demo's files
# (bench/figures.py; tests/test_readme.py checks the README against docs/figures.json).
figures: demo
	$(BIN)/python bench/figures.py demo out
	$(BIN)/python bench/figures.py readme

# One BLAS thread per process: the tests (and the renders they run in worker processes)
# share 2 cores, and threaded BLAS on a loaded machine made a bundle adjustment 20x slower.
# Two pytest workers (pytest-xdist), each test file on one worker: the suite uses both
# cores (312 CPU-s; 250 s serial, about 160 s on two idle cores).
test: $(STAMP)
	OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 $(BIN)/python -m pytest -q -n 2 --dist loadfile --durations=10

clean:
	rm -rf out .pytest_cache

bench: $(STAMP)
	$(BIN)/python bench/speed.py
	$(BIN)/python bench/diagnose.py
	$(BIN)/python bench/measure.py
	$(BIN)/python bench/measure.py --whole
	$(BIN)/python bench/render.py
	$(BIN)/python bench/simulate.py
	$(BIN)/python bench/walkthrough.py
