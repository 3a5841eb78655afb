# hfsmc: the one entry point. `make test` and `make demo` set everything up on a
# fresh Debian machine: Debian packages through apt-get (sudo when not root,
# skipped when present) and a virtualenv .venv with the package and its tools.

PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
DEB_PACKAGES := graphviz tmux
EXAMPLES := $(foreach d,$(wildcard examples/*/),$(wildcard $(d)$(notdir $(d:/=)).yaml))
PYTEST_ARGS ?=

.PHONY: all setup deps test demo bench golden lint examples clean

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
	$(BIN)/python -m pip install -q -e '.[dev]'
	touch $@

setup: deps $(STAMP)

lint: setup
	$(BIN)/ruff check hfsmc tests bench templates/python
	$(BIN)/mypy
	$(BIN)/mypy --strict $(wildcard templates/python/hfsmc_*.py)

test: lint
	$(BIN)/pytest $(PYTEST_ARGS)

# The demo builds the blinker component and runs it with the live view for a few
# seconds, then stops it with Ctrl+C (SIGINT): it goes through its on_interrupt
# state and exits cleanly (status 130). The drone issue replaces it with a flight.
DEMO_SECONDS ?= 6
demo: setup
	$(BIN)/hfsmc check $(EXAMPLES)
	@mkdir -p build/diagrams
	@for m in $(EXAMPLES); do \
	  $(BIN)/hfsmc diagram $$m -o build/diagrams/$$(basename $${m%.*}).svg || exit 1; \
	done
	$(BIN)/hfsmc build -t python examples/blinker/blinker.yaml -o build/blinker
	@echo "== running build/blinker/blinker.py --display for $(DEMO_SECONDS) s, then Ctrl+C =="
	@timeout --preserve-status -s INT $(DEMO_SECONDS) $(BIN)/python build/blinker/blinker.py --display \
	  --trace build/blinker.trace; st=$$?; \
	  if [ $$st -ne 130 ] && [ $$st -ne 0 ]; then echo "demo: blinker exited with $$st"; exit 1; fi; \
	  echo; echo "== blinker stopped cleanly (exit $$st): $$(tail -n 1 build/blinker.trace)"; \
	  echo "   trace: build/blinker.trace   diagrams: build/diagrams/*.svg"; \
	  echo "   watch it live: $(BIN)/python build/blinker/blinker.py --monitor 8765 &  $(BIN)/hfsmc view 8765"

bench: setup
	$(BIN)/python -m pip install -q -e '.[bench]'
	$(BIN)/python bench/frontend.py --json bench/results.json
	$(BIN)/python bench/component.py --json bench/results.json

golden: setup
	$(BIN)/python tests/regen_golden.py

examples: setup
	$(BIN)/hfsmc check --strict $(EXAMPLES)

clean:
	rm -rf build dist *.egg-info .pytest_cache .mypy_cache .ruff_cache bench/_work
