"""Frames split over the datagrams to one UDP destination (mavscope.mavlink.receivers).

The receivers keep their parser's state from one datagram to the next (PX4's mavlink_receiver, QGroundControl's
UDPLink, ArduPilot's UDP ports, pymavlink's mavudp all feed one parser every byte a port gets), so a frame
split over two datagrams is read whole. The expected answers come from MAVLink's own C parser reading the
datagrams one after another with one parser (tests/support/cparser.py, `keep=True`), against the same parser
reset at each datagram for what a per-datagram reader sees. The frames are pymavlink's; the crafted ARM
whose second half is a clean HEARTBEAT is laid out here by hand (COMMAND_LONG's wire order from pymavlink:
param1-7, command, target_system, target_component, confirmation).
"""

from __future__ import annotations

import struct
from pathlib import Path

import pytest
from fastcrc import crc16
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import all as mavlink

from mavscope.capture.base import LINKTYPE_ETHERNET, Record
from mavscope.capture.synth import udp_packet
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus, Frame
from mavscope.native import export as export_native
from mavscope.notes import note
from mavscope.pipeline.dissect import Dissector
from tests.mavlink.test_hidden_frames import arm, datagrams
from tests.support import pmav
from tests.support.builders import write_udp_pcap
from tests.support.cparser import CParser, require_c_parser
from tests.support.sources import same_tables

HEADERS = 42  # Ethernet, IPv4, UDP: where the payload starts in a record
GCS, VEHICLE, OTHER = ("10.0.0.2", 14550), ("10.0.0.1", 14555), ("10.0.0.9", 14555)


@pytest.fixture(scope="module")
def cparser() -> CParser:
    return require_c_parser()


def split_arm() -> bytes:
    """An ARM COMMAND_LONG (255/190 to 1/1) whose last 21 bytes are a HEARTBEAT frame with a good CRC: sent
    as its first 24 bytes, then those 21, the second datagram is a clean HEARTBEAT to a per-datagram reader.

    The heartbeat (type 0x90, autopilot 1, base_mode 1, system_status 1, version 0) lies over param4's high
    half, param5-7, command (0x0190 = 400), target 1/1 and confirmation 0; param2 is tried until the
    command's CRC equals the heartbeat's."""
    hb_payload = struct.pack("<IBBBBB", 0, 0x90, 1, 1, 1, 0)
    hb_head = bytes([0xFD, 9, 0, 0, 3, 1, 1, 0, 0, 0])
    hb_crc = crc16.mcrf4xx(bytes([mavlink.mavlink_map[0].crc_extra]), crc16.mcrf4xx(hb_head[1:] + hb_payload))
    inner = hb_head + hb_payload  # 19 bytes: COMMAND_LONG's payload[14:33]
    head = bytes([0xFD, 33, 0, 0, 40, 255, 190, 76, 0, 0])
    extra = bytes([mavlink.mavlink_map[76].crc_extra])
    for p2 in range(1 << 16):
        payload = struct.pack("<fHH", 1.0, 0, p2) + bytes(6) + inner  # param1 1.0, param2 (2 bytes tried), ...
        if crc16.mcrf4xx(extra, crc16.mcrf4xx(head[1:] + payload)) == hb_crc:
            return head + payload + struct.pack("<H", hb_crc)
    raise AssertionError("no param2 gives the heartbeat's CRC")


def test_an_arm_whose_second_half_is_a_clean_heartbeat(cli, tmp_path: Path, cparser: CParser) -> None:  # type: ignore[no-untyped-def]
    x = split_arm()
    hb = pmav.heartbeat(pmav.mav2())
    d1, d2 = hb + x[:24], x[24:]
    # the receivers read the ARM across the datagrams; a parser reset at each datagram reads the HEARTBEAT
    assert cparser.frames([d1, d2], keep=True) == [{(0, 21)}, {(-24, 45)}]
    assert cparser.frames([d1, d2]) == [{(0, 21)}, {(0, 21)}]
    m = mavlink.MAVLink(None)
    m.robust_parsing = True
    assert [msg.get_type() for msg in m.parse_buffer(d1 + d2) or []] == ["HEARTBEAT", "COMMAND_LONG"]  # pymavlink's
    path = write_udp_pcap(tmp_path / "split.pcap", [(GCS, VEHICLE, d1), (GCS, VEHICLE, d2), (GCS, VEHICLE, hb)])
    rows = {}
    for engine in ("", "1"):  # native and pure: the second datagram is clean, the walker hands it back
        rows[engine] = cli.jsonl(path, environ={"MAVSCOPE_PURE": engine})
    assert rows[""] == rows["1"]
    got = [(r["frame"], r["index"], r["msgname"], r["crc_status"], [n["code"] for n in r["notes"]]) for r in rows[""]]
    assert got == [(1, 1, "HEARTBEAT", "ok", []), (1, 2, "COMMAND_LONG", "truncated", ["truncated-frame"]),
                   (2, 1, "COMMAND_LONG", "ok", ["split-frame"]), (2, 2, "HEARTBEAT", "ok", []),
                   (3, 1, "HEARTBEAT", "ok", [])]
    split = rows[""][2]
    # where it begins in the file: pcap header, record header, Ethernet/IP/UDP, the heartbeat before it
    assert split["notes"][0]["offset"] == 24 + 16 + HEADERS + len(hb)
    assert split["fields"]["command"] == 400 and split["fields"]["param1"] == 1.0
    assert "first 24 of 45 bytes came in record 1" in split["notes"][0]["message"]
    for engine in ("", "1"):
        assert cli.json("stats", path, environ={"MAVSCOPE_PURE": engine}) == cli.json(
            "stats", path, environ={"MAVSCOPE_PURE": "1"})
    status, out, _ = cli("read", path)
    assert status == 0 and "[split over datagrams: the receivers read it whole]" in out


def test_hosts_mix_only_as_a_condition_and_a_snapped_datagram_carries_nothing(dialect: Dialect, tmp_path: Path) -> None:
    a = arm()
    frames = dissect_udp(dialect, [(GCS, VEHICLE, a[:20]), (GCS, OTHER, a[20:]), (GCS, VEHICLE, a[20:])])
    # VEHICLE's socket gets records 1 and 3: it reads the ARM in record 3. A socket on port 14555 that both
    # 10.0.0.1 and 10.0.0.9 reach (one host's two addresses: the capture cannot tell) reads it in record 2,
    # which is said as that condition (mavscope.mavlink.receivers: the port's wildcard state)
    assert [(f.record, f.msgname, f.crc_status) for f in frames] == [
        (1, "COMMAND_LONG", CrcStatus.TRUNCATED), (2, "COMMAND_LONG", CrcStatus.OK), (3, "COMMAND_LONG", CrcStatus.OK)]
    assert frames[1].notes[0].message.startswith("if 10.0.0.1:14555, 10.0.0.9:14555 reach one receiving socket")
    assert not frames[2].notes[0].message.startswith("if ")
    assert frames[2].span == (1, 3) and frames[2].raw == a
    # the capture kept only 20 bytes of the first datagram: what the receiver had is unknown
    cut = Record(1, 1.0, LINKTYPE_ETHERNET, udp_packet(*GCS, *VEHICLE, a)[: HEADERS + 20], 0, HEADERS + len(a),
                 (note("record-snapped", f"{HEADERS + 20} of {HEADERS + len(a)} bytes captured", 0),))  # as the reader
    rest = Record(2, 2.0, LINKTYPE_ETHERNET, udp_packet(*GCS, *VEHICLE, a[20:]), 1000, HEADERS + len(a) - 20)
    frames = [i for i in Dissector(dialect).run([cut, rest]) if isinstance(i, Frame)]
    assert [(f.record, f.crc_status) for f in frames] == [(1, CrcStatus.TRUNCATED)]


def dissect_udp(dialect: Dialect, packets: list[tuple[tuple[str, int], tuple[str, int], bytes]]) -> list[Frame]:
    """The packets as records 1.. at file offsets 1000, 2000, ... (payload HEADERS bytes in)."""
    records = [Record(i + 1, float(i + 1), LINKTYPE_ETHERNET, udp_packet(*src, *dst, d), 1000 * (i + 1),
                      HEADERS + len(d)) for i, (src, dst, d) in enumerate(packets)]
    return [i for i in Dissector(dialect).run(records) if isinstance(i, Frame)]


@settings(max_examples=200, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.lists(datagrams(), min_size=1, max_size=3).map(b"".join),
       cuts=st.lists(st.integers(1, 120), min_size=1, max_size=8))
def test_the_datagrams_to_one_destination_as_the_c_library_reads_them(
        dialect: Dialect, cparser: CParser, data: bytes, cuts: list[int]) -> None:
    """Mutated frames cut into datagrams at random places, all to one destination: every frame the C
    library reads, going on from one datagram to the next, is one mavscope shows with a good CRC (in a
    datagram, or split over them), every frame called split or hidden is one it reads, none twice."""
    parts, off = [], 0
    for i in range(len(data)):
        size = cuts[i % len(cuts)]
        if off >= len(data):
            break
        parts.append(data[off : off + size])
        off += size
    starts = [sum(len(p) for p in parts[:i]) for i in range(len(parts))]
    reads = {(starts[n] + s, size) for n, found in enumerate(cparser.frames(parts, keep=True)) for s, size in found}
    frames = dissect_udp(dialect, [(GCS, VEHICLE, p) for p in parts])

    def where(f: Frame) -> tuple[int, int]:
        record, pos = divmod(f.offset - HEADERS, 1000)  # type: ignore[operator]
        return starts[record - 1] + pos, len(f.raw)

    shown = {where(f) for f in frames if f.crc_status is CrcStatus.OK}
    assert reads <= shown, (data.hex(), cuts, reads - shown)
    claimed = [where(f) for f in frames if any(n.code in ("split-frame", "hidden-frame") for n in f.notes)]
    assert set(claimed) <= reads and len(set(claimed)) == len(claimed), (data.hex(), cuts)


@pytest.mark.parametrize("seed", range(6))
def test_both_engines_agree_on_split_frames(cli, tmp_path: Path, seed: int) -> None:  # type: ignore[no-untyped-def]
    """Frames (some mutated) cut at random places into datagrams to two destinations, interleaved, with
    clean datagrams among them: the native walker hands back what Python must see, so `read` and `stats`
    are the same on both engines (MAVSCOPE_PURE=1 is the reference)."""
    import random

    from tests.mavlink.test_hidden_frames import PARTS

    rng = random.Random(seed)
    packets = [(GCS, VEHICLE, arm()[:30]), (GCS, VEHICLE, arm()[30:])]  # one split frame at least
    for dst in [VEHICLE, OTHER] * 6:
        data = bytearray(b"".join(rng.choice(PARTS) for _ in range(3)))
        if rng.random() < 0.5:
            data[rng.randrange(len(data))] ^= 0x10
        cut = rng.randrange(1, len(data))
        packets += [(GCS, dst, bytes(data[:cut])), (GCS, dst, pmav.heartbeat(pmav.mav2())) if rng.random() < 0.3
                    else (GCS, dst, bytes(data[cut:]))]
        if rng.random() < 0.5:
            packets.append((GCS, dst, bytes(data[cut:])))
    path = write_udp_pcap(tmp_path / f"split{seed}.pcap", packets)
    native, pure = ({"MAVSCOPE_PURE": ""}, {"MAVSCOPE_PURE": "1"})
    rows = cli.jsonl(path, environ=pure)
    assert any(n["code"] == "split-frame" for r in rows for n in r["notes"])
    assert cli.jsonl(path, environ=native) == rows
    assert cli.json("stats", path, environ=native) == cli.json("stats", path, environ=pure)
    if export_native._native is not None:
        same_tables(path)  # the export's tables, native and pure
