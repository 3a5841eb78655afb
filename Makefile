# hfsmc: the one entry point. `make test` and `make demo` set everything up on a
# fresh Debian machine: Debian packages through apt-get (sudo when not root,
# skipped when present) and a virtualenv .venv with the package and its tools.

PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
# graphviz: diagrams, drawn in Liberation Sans (fonts-liberation: Helvetica's and Arial's metrics, so
# labels measure the same on every machine, docs/diagrams.md); tmux: the live-view tests; chromium: the web view's tests;
# the rest: C++ components (CMake, g++, Eigen, OpenCV, yaml-cpp for NAME.yaml; Ninja and
# ccache, which the generated CMake projects use when present, for shorter builds);
# libboost-dev: bench/cpp.py's Boost.MSM and Boost.Statechart peers (headers only);
# cyclonedds-dev and cyclonedds-tools (idlc): the C++ components' ROS 2 interface (docs/ros2.md);
# libfastrtps-dev: Fast DDS, the other vendor the ROS 2 tests talk to.
DEB_PACKAGES := graphviz fonts-liberation tmux cmake g++ make pkg-config libeigen3-dev libopencv-dev libyaml-cpp-dev libboost-dev ninja-build ccache chromium chromium-driver cyclonedds-dev cyclonedds-tools libfastrtps-dev
EXAMPLES := $(foreach d,$(wildcard examples/*/),$(wildcard $(d)$(notdir $(d:/=)).yaml))
PYTEST_ARGS ?=
# `make test` runs the tests on parallel workers (pytest-xdist): the suite mostly waits on
# real time (flights, real-clock runs, terminals, a browser), not on the cores, so one worker
# more than the cores (3 on 2 cores, at most 8). Each test file is one group on one worker
# (its C++ builds and other module fixtures made once); the longest files start first
# (tests/conftest.py: LONGEST_FIRST, SPREAD). PYTEST_JOBS=0 runs serially.
PYTEST_JOBS ?= $(shell n=$$(nproc 2>/dev/null || echo 2); echo $$(( n + 1 > 8 ? 8 : n + 1 )))

.PHONY: all setup deps test demo bench golden lint examples clean fuzz soak editor-bundle

all: test

deps:
	@missing=""; \
	for p in $(DEB_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	$(PY) -c 'import ensurepip, venv' 2>/dev/null || missing="$$missing python3-venv"; \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages:$$missing"; \
	  $(SUDO) apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $$missing; \
	fi

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[dev,lsp,ros2]'
	touch $@

setup: deps $(STAMP)

# The editor's page uses CodeMirror 6, bundled once into hfsmc/web/static/vendor/codemirror.js
# (committed, so neither pip install nor the tests need node). This rebuilds it with npm from
# the versions pinned in its package-lock.json.
editor-bundle:
	cd hfsmc/web/static/vendor && npm ci --no-audit --no-fund && npm run build

lint: setup
	$(BIN)/ruff check hfsmc tests bench templates/python scripts
	$(BIN)/mypy
	$(BIN)/mypy --strict $(wildcard templates/python/hfsmc_*.py)
	$(BIN)/lint-imports --no-cache

test: lint
	$(BIN)/pytest -n $(PYTEST_JOBS) --dist loadfile --no-loadscope-reorder --durations=15 $(PYTEST_ARGS)

# The demo flies the paper's follow_colors mission: it starts the simulator,
# builds the Python component and runs it with the live view (about 2.5 min),
# then prints the mission result (scripts/demo.sh). Before, it checks and
# draws every example into build/diagrams/.
demo: setup
	$(BIN)/hfsmc check $(EXAMPLES)
	@mkdir -p build/diagrams
	@for m in $(EXAMPLES); do \
	  $(BIN)/hfsmc diagram $$m -o build/diagrams/$$(basename $${m%.*}).svg || exit 1; \
	done
	BIN=$(BIN) scripts/demo.sh

bench: setup
	$(BIN)/python -m pip install -q -e '.[bench]'
	$(BIN)/python bench/frontend.py --json bench/results.json
	$(BIN)/python bench/component.py --json bench/results.json
	$(BIN)/python bench/vision.py --json bench/results.json
	$(BIN)/python bench/cpp.py --json bench/results.json
	$(BIN)/python bench/mcap.py --json bench/results.json
	$(BIN)/python bench/edit.py --json bench/results.json
	$(BIN)/python bench/editor.py --json bench/results.json
	$(BIN)/python bench/cppbuild.py --json bench/results.json
	$(BIN)/python bench/web.py --json bench/results.json
	$(BIN)/python bench/realtime.py --json bench/results.json
	$(BIN)/python bench/ros2.py --json bench/results.json
	$(BIN)/python bench/ros2_rpc.py --json bench/results.json
	$(BIN)/python bench/patrol.py --runs 3 --json bench/results.json
	$(BIN)/python bench/record.py --json bench/results.json
	$(BIN)/python bench/lockstep.py --json bench/results.json

# A longer run of the front end's fuzzer than `make test` does (crashes become
# files in tests/invalid/): FUZZ_SECONDS=3600 make fuzz.
FUZZ_SECONDS ?= 300
fuzz: setup
	$(BIN)/python bench/fuzz.py --seconds $(FUZZ_SECONDS)

# Fly follow_colors in a loop (not in CI): every mission must succeed, memory
# grow < 5 %, overruns not grow. SOAK_MINUTES=30 make soak; results in build/soak.json.
SOAK_MINUTES ?= 30
soak: setup
	$(BIN)/python scripts/soak.py --minutes $(SOAK_MINUTES) --json build/soak.json

golden: setup
	$(BIN)/python tests/regen_golden.py

examples: setup
	$(BIN)/hfsmc check --strict $(EXAMPLES) $(wildcard examples/lib/*.yaml)

clean:
	rm -rf build dist *.egg-info .pytest_cache .mypy_cache .ruff_cache bench/_work
