"""`read -q -z ...` against `tshark -q -z ...` on the same captures: the frame counts where the names mean the same.

tshark counts packets, mavscope MAVLink frames: on the bundled captures whose every packet is one MAVLink
frame over UDP (checked here first: as many JSON lines as tshark packets), the conversations' and endpoints'
frame counts each way and io,stat's frames per interval (also with a filter) must be tshark's. Bytes
differ by design (tshark's are the link layer's, mavscope's the MAVLink frames') and are not compared.
tshark 4.0 (scripts/install-test-tools.sh); skipped with the reason where it is missing.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from tests.conftest import CAPTURES, Cli

NAMES = ("gcs_takeover.pcap", "stats_loss.pcap", "mavlink_v1_udp.pcap")


@pytest.fixture(scope="module")
def tshark_path() -> str:
    exe = shutil.which("tshark")
    if exe is None:
        pytest.skip("tshark is not installed (scripts/install-test-tools.sh installs it)")
    return exe


def _tshark(exe: str, capture: Path, *z: str) -> str:
    cmd = [exe, "-n", "-r", str(capture), "-q", *(a for s in z for a in ("-z", s))]
    got = subprocess.run(cmd, capture_output=True, text=True, timeout=300, check=False, env={"TZ": "UTC"})
    assert got.returncode == 0, got.stderr[-300:]
    return got.stdout


def _one_frame_a_packet(cli: Cli, exe: str, capture: Path) -> None:
    frames = len(cli("read", str(capture), "-T", "jsonl").out.splitlines())
    packets = len(subprocess.run([exe, "-n", "-r", str(capture)], capture_output=True, text=True, timeout=300,
                                 check=False).stdout.splitlines())
    assert frames == packets


def _pairs(text: str, frames_at: tuple[int, int]) -> dict[tuple[str, str], int]:
    """Frames each way of each conversation row: (A, B) A->B and (B, A) B->A."""
    out = {}
    for line in text.splitlines():
        m = re.match(r"(\S+)\s+<->\s+(\S+)\s+(.*)", line)
        if m:
            t = m.group(3).split()
            out[(m.group(2), m.group(1))] = int(t[frames_at[0]])  # "<-": B to A
            out[(m.group(1), m.group(2))] = int(t[frames_at[1]])  # "->": A to B
    return out


@pytest.mark.parametrize("name", NAMES)
def test_conversations_and_endpoints_count_tsharks_frames(name: str, tshark_path: str, cli: Cli) -> None:
    capture = CAPTURES / name
    _one_frame_a_packet(cli, tshark_path, capture)
    ours = cli("read", str(capture), "-q", "-z", "conv,udp", "-z", "endpoints,udp").out
    ref = _tshark(tshark_path, capture, "conv,udp", "endpoints,udp")
    # tshark 4.0 writes bytes as "4461 bytes" / "98 kB" (two words): its frame counts are words 0 and 3
    assert _pairs(ours, (0, 2)) == _pairs(ref, (0, 3)) != {}

    def ends(text: str) -> dict[tuple[str, str], tuple[int, int, int]]:
        rows = [line.split() for line in text.split("Endpoints")[1].splitlines()]
        return {(r[0], r[1]): (int(r[2]), int(r[4]), int(r[6])) for r in rows if len(r) == 8 and r[1].isdigit()}

    assert ends(ours) == ends(ref) != {}


@pytest.mark.parametrize("flt", [None, "mavlink.msgid==0"])
@pytest.mark.parametrize("name", NAMES[:2])
def test_io_stat_counts_tsharks_frames(name: str, flt: str | None, tshark_path: str, cli: Cli) -> None:
    """Frames per 5 s interval from the first record; with a filter, the frames it matches. tshark runs
    without the Lua dissector here, so the HEARTBEATs are named by their size: an unsigned MAVLink 2
    HEARTBEAT is 21 bytes (10 of header, 9 of payload, 2 of CRC), a UDP length of 29, and on these captures
    no other message has that size (the counts with the filter would differ otherwise)."""
    capture = CAPTURES / name
    spec = "io,stat,5" + (f",{flt}" if flt else "")
    ours = cli("read", str(capture), "-q", "-z", spec).out
    ref = _tshark(tshark_path, capture, "io,stat,5" + (",udp.length==29" if flt else ""))

    def rows(text: str) -> list[int]:
        return [int(m.group(1)) for m in re.finditer(r"<> *(?:\d+|Dur) *\| *(\d+) *\|", text)]

    assert rows(ours) == rows(ref) and rows(ours)
