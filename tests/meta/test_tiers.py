"""The test tiers of tests/support/tiers.py do what docs/testing.md ("Tiers") says: the fast tier's property
tests run a tenth of their examples, a sweep keeps its representatives fast, every module keeps a fast test."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from fnmatch import fnmatchcase
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.conftest import REAL_CAPTURES, ROOT
from tests.support import tiers


def _counting_property(asked: int) -> tuple[list[int], object]:
    calls: list[int] = []

    @settings(max_examples=asked, database=None)
    @given(st.integers())
    def prop(x: int) -> None:
        calls.append(x)

    return calls, prop


def test_the_fast_tier_runs_a_tenth_of_what_a_tests_settings_ask() -> None:
    """By hypothesis's definition of max_examples: up to 300 examples of integers() (an unbounded strategy,
    so far more than 30 distinct ones); capped, 300 // 10 = 30 at most."""
    full_calls, full = _counting_property(300)
    full()  # type: ignore[operator]
    capped_calls, capped = _counting_property(300)
    tiers.cap_examples(capped)  # type: ignore[arg-type]
    capped()  # type: ignore[operator]
    assert len(full_calls) > 30
    assert 0 < len(capped_calls) <= 30
    assert tiers.fast_examples(300) == 30 and tiers.fast_examples(20) == 5 and tiers.fast_examples(3) == 3


def test_a_sweep_keeps_its_representatives_or_its_first(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(tiers, "SLOW", ("m.py::whole", "m.py::one[2]"))
    monkeypatch.setattr(tiers, "SWEEPS", {"m.py::sweep": ("*b*",), "m.py::gone": ("nothing-matches",)})
    ids = ["m.py::sweep[a]", "m.py::sweep[b-1]", "m.py::sweep[c]", "m.py::gone[x]", "m.py::gone[y]",
           "m.py::whole[1]", "m.py::whole[2]", "m.py::one[1]", "m.py::one[2]", "m.py::fast", "m.py::sweeping[a]"]
    assert tiers.slow_ids(ids) == {"m.py::sweep[a]", "m.py::sweep[c]", "m.py::gone[y]", "m.py::whole[1]",
                                   "m.py::whole[2]", "m.py::one[2]"}


def test_a_capture_sweep_keeps_the_representatives_and_what_names_no_capture() -> None:
    """Five bundled captures (a sweep) keep the two BUNDLED_KEPT and the parametrization naming none; three
    (not a sweep, SWEEP_CAPTURES is 4) keep all. Names as captures/ holds them."""
    sweep = ["m.py::t[clock_skew.pcap-json]", "m.py::t[damaged.pcap-json]", "m.py::t[gps_spoof.pcap-json]",
             "m.py::t[signed_udp.pcap-json]", "m.py::t[px4_sitl.tlog-json]", "m.py::t[empty-json]"]
    few = ["m.py::u[clock_skew.pcap]", "m.py::u[gps_spoof.pcap]", "m.py::u[px4_sitl.tlog]"]
    assert tiers.slow_ids(sweep + few) == {"m.py::t[clock_skew.pcap-json]", "m.py::t[gps_spoof.pcap-json]",
                                           "m.py::t[px4_sitl.tlog-json]"}


def test_every_module_keeps_a_fast_test_and_every_rule_names_tests(tmp_path: Path) -> None:
    """Over a whole collection (this test is itself in the slow tier): a module with no fast test is listed in
    WHOLLY_SLOW and every module listed there has none; every SLOW pattern and SWEEPS entry still names
    collected tests (a renamed test would otherwise silently change tier)."""
    if not REAL_CAPTURES.is_dir():
        pytest.skip(f"{REAL_CAPTURES} is absent: the sweeps over the real captures are not collected")
    report = tmp_path / "tiers.json"
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST_")} | {tiers.REPORT_ENV: str(report)}
    proc = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider",
                           "-p", "no:xdist", "-o", "addopts=", "tests"],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=600, check=False)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    given_tiers: dict[str, bool] = json.loads(report.read_text(encoding="utf-8"))
    modules: dict[str, list[bool]] = {}
    for nodeid, slow in given_tiers.items():
        modules.setdefault(nodeid.split("::")[0], []).append(slow)
    without_fast = {m for m, slows in modules.items() if all(slows)}
    assert without_fast == set(tiers.WHOLLY_SLOW)
    bases = {n.split("[")[0] for n in given_tiers}
    unmatched = [p for p in tiers.SLOW if not (p in given_tiers if "[" in p else any(fnmatchcase(b, p) for b in bases))]
    assert not unmatched, f"SLOW patterns that name no test: {unmatched}"
    for base, keep in tiers.SWEEPS.items():
        params = [n[len(base) + 1:-1] for n in given_tiers if n.startswith(base + "[")]
        assert params, f"SWEEPS names {base}, which has no parametrization"
        missing = [k for k in keep if not any(fnmatchcase(p, k) for p in params)]
        assert not missing, f"SWEEPS keeps {missing} of {base}, which match none of its parametrizations"
