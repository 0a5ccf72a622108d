"""str.isdigit() is true for '²' and '٣', which int() refuses (or reads as another number): every number
the command line or the environment gives is taken only from ASCII digits, as one-line errors otherwise.
Found by `make fuzz` (keys target: `--cipher` METHOD '32\\x1d\\t')."""

from __future__ import annotations

import pytest

from tests.conftest import CAPTURES, Cli


@pytest.mark.parametrize("argv", [
    ("read", CAPTURES / "px4_sitl_udp.pcap", "-c", "²"),
    ("read", CAPTURES / "px4_sitl_udp.pcap", "--cipher", "²=xor:hex:00"),
    ("read", CAPTURES / "px4_sitl_udp.pcap", "--cipher", "3\x1d=xor:hex:00"),
    ("audit", CAPTURES / "securemav_udp.pcap", "--known-plaintext", "²=00"),
])
def test_non_ascii_digits_are_usage_errors(cli: Cli, argv: tuple[object, ...]) -> None:
    status, out, err = cli(*map(str, argv))
    assert status == 2 and err.startswith("mavscope: ") and err.count("\n") == 1, err
    assert "Traceback" not in err


def test_a_non_ascii_columns_value_is_ignored(cli: Cli) -> None:
    status, out, _ = cli("stats", CAPTURES / "px4_sitl_udp.pcap", environ={"COLUMNS": "٣"})
    assert status == 0 and out
