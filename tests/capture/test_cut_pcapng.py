"""A pcapng file cut short says so once: a file of fewer than 12 bytes that starts with the section
header's block type is a pcapng cut inside its first header (a review found 4 such bytes read as a raw
stream), and the record the reader makes to carry "cut short" is not decoded as a packet (which added
"Ethernet header needs 14 bytes, packet has 0")."""

from __future__ import annotations

from pathlib import Path

import pytest

from mavscope.capture.detect import detect_kind
from tests.conftest import CAPTURES, Cli

SLL2 = CAPTURES / "px4_sitl_sll2.pcapng"


@pytest.mark.parametrize("cut", [4, 7, 11])
def test_cut_inside_the_section_header(cli: Cli, tmp_path: Path, cut: int) -> None:
    path = tmp_path / "cut.bin"  # the name says nothing: the content decides
    path.write_bytes(SLL2.read_bytes()[:cut])
    assert detect_kind(path) == "pcapng"
    status, out, err = cli("read", str(path))
    assert (status, out) == (0, "")
    assert err.splitlines() == [f"mavscope: {path}: record 1: offset 0: file ends {cut} bytes into a block header",
                                f"mavscope: no MAVLink frames found in {path} ({cut} bytes, detected as pcapng)"]


def test_a_block_cut_short_is_one_line(cli: Cli, tmp_path: Path) -> None:
    data = SLL2.read_bytes()
    shb_len = int.from_bytes(data[4:8], "little")  # the section header block's total length (by hand: 72)
    path = tmp_path / "cut.pcapng"
    path.write_bytes(data[: shb_len - 52])
    _, _, err = cli("read", str(path))
    assert err.splitlines() == [f"mavscope: {path}: record 1: block at offset 0 has 20 of {shb_len} bytes: file cut "
                                "short", f"mavscope: no MAVLink frames found in {path} (20 bytes, detected as pcapng)"]


def test_twelve_bytes_with_a_wrong_byte_order_magic_stay_raw(tmp_path: Path) -> None:
    """With the header's first 12 bytes present, a byte-order magic that is neither 0x1A2B3C4D nor its
    byte swap is not trusted as pcapng: the bytes are scanned as a raw stream (frames inside are found)."""
    path = tmp_path / "x.pcapng"
    path.write_bytes(b"\x0a\x0d\x0d\x0a" + (28).to_bytes(4, "little") + b"\x00\x00\x00\x00" + bytes(16))
    assert detect_kind(path) == "raw"
