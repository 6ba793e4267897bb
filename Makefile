# Two commands do all set-up on a fresh machine: `make demo` and `make test`.
# Both create .venv if it is missing and install the project with the pinned stack (constraints.txt).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
PKGS   := synth tactile_learn
LINTED := synth tactile_learn tests scripts

.PHONY: demo test lint stress bench bench-speed models clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade "pip>=23.2"

$(STAMP): pyproject.toml constraints.txt | $(BIN)/python
	$(BIN)/python -m pip install --quiet -c constraints.txt -e ".[all,dev]"
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/tactile-learn demo

lint: $(STAMP)
	$(BIN)/ruff check $(LINTED)
	$(BIN)/ruff format --check $(LINTED)
	$(BIN)/mypy

# One BLAS/OpenMP thread: the suite's arrays are tiny, and threaded BLAS stalls when the cores are shared
# (one test file: 150 s threaded vs 12 s single-threaded under load; the same CPU time on a quiet machine).
test: lint
	OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 $(BIN)/python -m pytest -q

# Longer property-based profile: many more hypothesis examples per test, with a summary.
stress: $(STAMP)
	TACTILE_STRESS=1 $(BIN)/python -m pytest -q -m stress

bench: $(STAMP)
	$(BIN)/tactile-learn bench --task all --reference --json results/bench.json --plot results/bench.png

# Issue 15's figures from one run: simulator speed, per-frame overhead, gating, large skins, the
# strips Pareto front (about 25 minutes on 2 cores); results/speed.md checks every floor.
bench-speed: $(STAMP)
	test -d data/strips16-test || $(BIN)/tactile-learn generate --scene strips16 --n 4000 --seed 3 --out data/strips16-test --quiet
	$(BIN)/python scripts/thermal_sim_speed.py --scene thermal --scene thermal_wns --json results/thermal_sim_speed.json
	$(BIN)/python scripts/latency_overhead.py --rounds 15 --json results/latency_overhead.json
	$(BIN)/python scripts/strips_pareto.py --models models/strips16.onnx models/strips16_small.onnx \
		models/strips16_spheres.onnx --json results/strips_pareto.json
	$(BIN)/python scripts/speed_report.py --out results/speed.md

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .mypy_cache .ruff_cache
