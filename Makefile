# softtrack: set-up, main job and tests. `make quickstart` and `make test` work on a fresh clone.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: setup quickstart test test-slow test-all bench faults hostile readme-animation

$(STAMP): pyproject.toml constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -c constraints.txt -e '.[test]'
	touch $(STAMP)

setup: $(STAMP)

quickstart: setup
	$(BIN)/softtrack quickstart

test: setup
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy
	$(BIN)/python -m pytest -q -n 2 -m "not slow" --durations=15

# the tests marked slow (long trainings, sweeps killed, the README tour, the wheel installed
# outside the checkout: tests/conftest.py LONG_TESTS); CI runs them after `make test`
test-slow: setup
	$(BIN)/python -m pytest -q -n 2 -m slow --durations=15

test-all: setup
	$(BIN)/python -m pytest -q -n 2

# the fault-injection sweep (docs/faults.md): kills, full and read-only disks, corrupt files,
# hostile queries and specs; ends with its tally of lost / traceback / degraded faults
faults: setup
	$(BIN)/python -m pytest -q -n 2 -m faults -p no:randomly

# faults injected as a hostile user would, each command run whole (docs/faults.md); ~5 min
hostile: setup
	$(BIN)/python tests/hostile_sweep.py

bench: setup
	taskset -c 0 $(BIN)/python benchmarks/bench_engine.py
	taskset -c 0 $(BIN)/python benchmarks/bench_env.py

# the README's first picture: the best shipped controller with contact on the circle, as a
# GIF and a film strip (docs/rendering.md); read-only on the shipped run
README_RUN := models/td3-sbx-128-mirror-tta-solid-3e6-seed4
readme-animation: setup
	$(BIN)/softtrack animate $(README_RUN) --trajectory circle --width 400 --height 300 \
		--fps 15 --out docs/images/readme-circle.gif --strip docs/images/readme-circle-strip.png
