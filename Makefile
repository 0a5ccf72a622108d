# Two entry points for a fresh machine: `make demo` and `make test`. Both are idempotent.
PYTHON ?= python3.11
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
TSTAMP := $(VENV)/.installed-test

.PHONY: demo test captures bench clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e .
	touch $@

$(TSTAMP): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP) $@

demo: $(STAMP)
	$(BIN)/mavscope read captures/px4_sitl_udp.pcap -c 40
	@echo
	@echo "--- the COMMAND_LONG (return to launch) frame in detail ---"
	$(BIN)/mavscope read captures/px4_sitl_udp.pcap -V -x -Y 'COMMAND_LONG' -c 1

test: $(TSTAMP)
	$(BIN)/python -m pytest -q

captures: $(TSTAMP)
	$(BIN)/python scripts/make_captures.py captures

bench: $(TSTAMP)
	$(BIN)/python benchmarks/bench_read.py

clean:
	rm -rf $(VENV) .pytest_cache .hypothesis
