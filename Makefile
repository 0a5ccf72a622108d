# Two entry points for a fresh machine: `make demo` and `make test`. Both are idempotent.
PYTHON ?= python3.11
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
TSTAMP := $(VENV)/.installed-test

.PHONY: demo test test-slow lint captures bench snapshots fuzz fuzz-native clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

# The C extension is compiled by the install: a change to its sources installs again.
NATIVE_SRC := setup.py $(wildcard src/mavscope_native/*.c src/mavscope_native/*.h)

$(STAMP): pyproject.toml $(NATIVE_SRC) | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e .
	touch $@

# MAVProxy for the cross-checks that use its decoders (pure Python modules); without its dependencies,
# which are its GUI's (OpenCV, VTK: hundreds of MB) and which those modules do not import
$(TSTAMP): pyproject.toml $(NATIVE_SRC) | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[test]'
	$(BIN)/python -m pip install --quiet --no-deps 'MAVProxy==1.8.75'
	touch $(STAMP) $@

demo: $(STAMP)
	@echo "--- mavscope read: a PX4 SITL session (first 25 frames) ---"
	$(BIN)/mavscope read captures/px4_sitl_udp.pcap -c 25
	@echo
	@echo "--- a damaged capture: bad CRCs, garbage, truncation, unknown ids are reported, not dropped ---"
	$(BIN)/mavscope read captures/damaged.pcap
	@echo
	@echo "--- the first waypoint of the mission upload in detail (-Y filter, -V tree, -x hex) ---"
	$(BIN)/mavscope read captures/px4_sitl_udp.pcap -Y 'MISSION_ITEM_INT.command == MAV_CMD_NAV_WAYPOINT' -c 1 -V -x
	@echo "--- the return-to-launch command as JSON Lines (-T jsonl) ---"
	$(BIN)/mavscope read captures/px4_sitl_udp.pcap -Y 'COMMAND_LONG.command == MAV_CMD_NAV_RETURN_TO_LAUNCH' -T jsonl

# one test process per core (pytest-xdist): the suite is CPU-bound and its tests are independent.
# Two tiers (docs/testing.md, "Tiers"; tests/support/tiers.py): `test` guards every behaviour with a tenth of
# each property test's examples and one or two representatives of each sweep; `test-slow` runs the rest (the
# sweeps over every capture, scale tests, mypy) and every property test with all its examples. CI runs both.
test: $(TSTAMP)
	$(BIN)/python -m pytest -q -n auto -m "not slow"

test-slow: $(TSTAMP)
	HYPOTHESIS_PROFILE=full $(BIN)/python -m pytest -q -n auto -m "slow or hypothesis"

lint: $(TSTAMP)
	$(BIN)/ruff check mavscope scripts benchmarks tests
	$(BIN)/mypy

captures: $(TSTAMP)
	$(BIN)/python scripts/make_captures.py captures

bench: $(TSTAMP)
	$(BIN)/python benchmarks/bench_read.py

# coverage-guided fuzzing (atheris) of the readers and pipeline, TCP reassembly, filters, key specs
FUZZ_SECONDS ?= 60
fuzz: $(TSTAMP)
	$(BIN)/python -m tests.fuzz.run $(FUZZ_SECONDS)

# libFuzzer with ASan/UBSan over the C core of the native engine (needs clang; docs/native.md)
FUZZ_NATIVE_SECONDS ?= 600
fuzz-native: $(TSTAMP)
	scripts/fuzz-native.sh $(FUZZ_NATIVE_SECONDS)

snapshots: $(TSTAMP)
	$(BIN)/python -m pytest --snapshot-update tests/tui/test_snapshots.py

clean:
	rm -rf $(VENV) .pytest_cache .hypothesis build fuzz/build mavscope/_native*.so
