"""The sources of valid MAVLink a dissector remembers are bounded, and the bound is said (issue 35, item 7).

`live --udp` kept every source endpoint that ever sent a valid frame (Dissector.mavlink_endpoints), and a
HEARTBEAT needs no key: 200,000 spoofed sources grew the process by 84 MB. The set now takes at most
MAX_MAVLINK_ENDPOINTS, the first ones kept (a flood after the vehicle churns nothing out), and each
newcomer it refuses is a `capacity` give-up, said on the 1st, 2nd, 4th, 8th... (notes.GivenUp).

Expected answers, from the capture built here: one genuine vehicle (10.9.9.9:14555) sends first, then N
spoofed sources (10.0.x.y:1024+i) one datagram each, so the set fills at the (CAP-1)th spoofed source and
the k-th refusal is record 1 + CAP + k - 1 ... worked out below from those counts, not from mavscope.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mavscope.capture.detect import open_capture
from mavscope.endpoint import Endpoint
from mavscope.mavlink.dialect import Dialect
from mavscope.pipeline.dissect import MAX_MAVLINK_ENDPOINTS as CAP
from mavscope.pipeline.dissect import Anomaly, Dissector
from tests.conftest import Cli
from tests.native.build import LINKTYPES, frame_v2, ipv4, link, pcap, udp
from tests.native.engines import same

VEHICLE = (bytes([10, 9, 9, 9]), 14555)


def _flood(path: Path, dialect: Dialect, spoofed: int, vehicle_after: int = 3) -> Path:
    """Record 1 from the vehicle, then `spoofed` records from distinct sources, then `vehicle_after` more from
    the vehicle: every datagram one CRC-valid HEARTBEAT (packed here with fastcrc and the CRC_EXTRA)."""
    # HEARTBEAT (id 0): custom_mode 0, type 2 (quadrotor), autopilot 3, base_mode 0, status 4, version 3
    hb = frame_v2(dialect.messages[0], 0, bytes([0, 0, 0, 0, 2, 3, 0, 4, 3]), 0, 1, 1)
    sources = [VEHICLE] + [(bytes([10, 0, (i >> 8) & 255, i & 255]), 1024 + i) for i in range(spoofed)]
    sources += [VEHICLE] * vehicle_after
    records = [(1000 + n, 0, link("ethernet", ipv4(addr, bytes([10, 0, 0, 1]), 17, udp(port, 14550, hb)), False))
               for n, (addr, port) in enumerate(sources)]
    path.write_bytes(pcap(records, LINKTYPES["ethernet"]))
    return path


def test_the_set_is_bounded_and_each_refusal_said(tmp_path: Path, dialect: Dialect) -> None:
    extra = 40  # sources past the bound
    path = _flood(tmp_path / "flood.pcap", dialect, CAP - 1 + extra)
    d = Dissector(dialect)
    with open_capture(path) as reader:
        items = list(d.run(reader))
    assert len(d.mavlink_endpoints) == CAP
    assert Endpoint("10.9.9.9", 14555) in d.mavlink_endpoints  # the vehicle, there before the flood, stays
    # Record 1 is the vehicle, records 2..CAP the first CAP-1 spoofed sources (the set is then full), so the
    # k-th refused source is record CAP + k; GivenUp says k = 1, 2, 4, 8, 16, 32 (40 refusals).
    said = [a.record for a in items if type(a) is Anomaly and any(n.code == "capacity" for n in a.notes)]
    assert said == [CAP + k for k in (1, 2, 4, 8, 16, 32)]
    # every datagram's frame is still shown: nothing the flood sent, nor the vehicle's later frames, vanishes
    frames = [f for f in items if type(f) is not Anomaly]
    assert len(frames) == 1 + CAP - 1 + extra + 3


def test_both_engines_say_it_on_the_same_records(tmp_path: Path, dialect: Dialect, cli: Cli) -> None:
    path = _flood(tmp_path / "flood.pcap", dialect, CAP + 5)
    out = same(cli, path).out  # native vs MAVSCOPE_PURE=1: equal stdout, stderr and status
    assert len(out.splitlines()) == 1 + CAP + 5 + 3
    audit = json.loads(cli("audit", path, "--json").out)
    codes = {f["code"] for f in audit["findings"]}
    assert "capacity" in codes


def test_the_native_walker_keeps_the_same_bound() -> None:
    from mavscope.native.core import _native as native

    if native is None:
        pytest.skip("built without the C extension")
    assert native.MAX_ENDPOINTS == CAP


def test_a_source_refused_again_adds_no_empty_anomaly(tmp_path: Path, dialect: Dialect) -> None:
    # the set full, then one refused source sending 5 datagrams: GivenUp says the 1st, 2nd and 4th give-up
    # (records CAP+1, CAP+2, CAP+4); the 3rd and 5th datagrams are refused too, and say nothing at all
    path = _flood(tmp_path / "flood.pcap", dialect, CAP - 1, vehicle_after=0)
    with path.open("ab") as out:
        pkt = link("ethernet", ipv4(bytes([10, 7, 7, 7]), bytes([10, 0, 0, 1]), 17,
                                    udp(4000, 14550, frame_v2(dialect.messages[0], 0, bytes(9), 0, 1, 1))), False)
        out.write(pcap([(9000 + n, 0, pkt) for n in range(5)], LINKTYPES["ethernet"])[24:])  # its records only
    with open_capture(path) as reader:
        anomalies = [a for a in Dissector(dialect).run(reader) if type(a) is Anomaly]
    assert [a.record for a in anomalies] == [CAP + 1, CAP + 2, CAP + 4]
    assert all(a.notes for a in anomalies)
