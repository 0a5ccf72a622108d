"""The bundled captures are exactly what scripts/make_captures.py builds, and pymavlink agrees with
expected.json about the frames of px4_sitl_udp.pcap."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import common as pm
from scapy.layers.inet import UDP
from scapy.utils import rdpcap

from tests.conftest import CAPTURES, ROOT

SCRIPT = ROOT / "scripts" / "make_captures.py"


@pytest.fixture(scope="module")
def regenerated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Run the generator as `make captures` does (the command line, in its own interpreter), so that the
    entry point and its package are what is checked, and nothing the tests imported can leak in."""
    out = tmp_path_factory.mktemp("captures")
    proc = subprocess.run([sys.executable, str(SCRIPT), str(out)], cwd=ROOT, capture_output=True, text=True,
                          timeout=300, check=False)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return out


@pytest.fixture(scope="module")
def expected() -> dict:
    return json.loads((CAPTURES / "expected.json").read_text(encoding="utf-8"))


def test_regenerated_files_are_identical(regenerated: Path) -> None:
    bundled = sorted(p.name for p in CAPTURES.iterdir() if p.is_file())
    built = sorted(p.name for p in regenerated.iterdir())
    assert built == bundled
    for name in built:
        assert (regenerated / name).read_bytes() == (CAPTURES / name).read_bytes(), f"{name} differs"


def test_counts_are_consistent(expected: dict) -> None:
    for name, e in expected.items():
        assert e["frames"] == len(e["frame_list"]) == len(e["frame_offsets"]) == len(e["frame_crc"]), name
        assert e["frames"] == e["crc_ok"] + e["crc_bad"] + e["crc_unchecked"] == e["v1"] + e["v2"], name
        assert e["truncated"] == len(e["truncated_list"]), name
        data = (CAPTURES / name).read_bytes()
        assert all(data[off] in (0xFD, 0xFE) for off in e["frame_offsets"]), name


def test_pymavlink_finds_the_expected_frames_in_px4_sitl_udp(expected: dict) -> None:
    """pymavlink's robust parser, one datagram at a time, reports the frames expected.json lists."""
    found = []
    for number, pkt in enumerate(rdpcap(str(CAPTURES / "px4_sitl_udp.pcap")), start=1):
        if UDP not in pkt:
            continue
        mav = pm.MAVLink(None)
        mav.robust_parsing = True
        msgs = [m for m in mav.parse_buffer(bytes(pkt[UDP].payload)) or [] if not isinstance(m, pm.MAVLink_bad_data)]
        for index, m in enumerate(msgs, start=1):
            found.append([number, index, m.get_srcSystem(), m.get_srcComponent(), m.get_seq(), m.get_msgId()])
    assert found == expected["px4_sitl_udp.pcap"]["frame_list"]
