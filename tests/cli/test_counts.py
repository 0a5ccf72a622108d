"""Numeric options take plain whole numbers in their range, and say so in one line otherwise (a review
found `stats --sparklines -3` and `plot --height 0` accepted)."""

from __future__ import annotations

import pytest

from tests.conftest import CAPTURES, Cli

CAPTURE = str(CAPTURES / "px4_sitl_udp.pcap")


@pytest.mark.parametrize(("argv", "error"), [
    (("stats", CAPTURE, "--sparklines", "-3"), "stats: argument --sparklines: a whole number (0 or more), not '-3'"),
    (("plot", CAPTURE, "HEARTBEAT.type", "--height", "0"),
     "plot: argument --height: a whole number of at least 2, not '0'"),
    (("plot", CAPTURE, "HEARTBEAT.type", "--width", "-1"),
     "plot: argument --width: a whole number (0 or more), not '-1'"),
    (("read", CAPTURE, "-c", "0"), "read: argument -c: a whole positive number of frames, not '0'"),
    (("read", CAPTURE, "-c", "+5"), "read: argument -c: a whole positive number of frames, not '+5'"),
    (("read", CAPTURE, "-c", "5_0"), "read: argument -c: a whole positive number of frames, not '5_0'"),
])
def test_out_of_range_numbers_are_usage_errors(cli: Cli, argv: tuple[str, ...], error: str) -> None:
    status, out, err = cli(*argv)
    assert (status, out, err) == (2, "", f"mavscope: {error}\n")


def test_the_smallest_allowed_values_run(cli: Cli) -> None:
    assert cli("stats", CAPTURE, "--sparklines", "0")[0] == 0
    assert cli("plot", CAPTURE, "GLOBAL_POSITION_INT.relative_alt", "--height", "2", "--width", "20")[0] == 0
    status, out, _ = cli("read", CAPTURE, "-c", "1")
    assert status == 0 and len(out.splitlines()) == 1
