"""UDP receivers are sockets, not addresses, and their bounds say what they give up (mavscope.mavlink.receivers).

The expected answers come from MAVLink's own C parser (tests/support/cparser.py, pymavlink's mavlink_helpers.h:
mavlink_parse_char and mavlink_frame_char_buffer) reading, with one parser kept from datagram to datagram
(`keep=True`), exactly the datagrams the vehicle's socket gets. Which those are is the receiving socket's
business: PX4 (Mavlink::init_udp: socket(AF_INET), bind INADDR_ANY), ArduPilot (SocketAPM::bind, a
sockaddr_in; `udpin:0.0.0.0:14550`) and QGroundControl (UDPLink: bind(QHostAddress::AnyIPv4)) bind the
wildcard address and a port, so the kernel hands them every datagram to that port the host gets: to its
unicast address, its subnet's broadcast address and 255.255.255.255 alike; a dual-stack socket bound to [::]
gets IPv4 datagrams as IPv4-mapped addresses and IPv6 ones too. The ARM is pymavlink's COMMAND_LONG
(tests/mavlink/test_hidden_frames.arm: MAV_CMD_COMPONENT_ARM_DISARM, param1 1).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mavscope.mavlink.receivers import MAX_PER_PORT, MAX_STATES
from tests.mavlink.test_hidden_frames import arm
from tests.support import pmav
from tests.support.cparser import CParser, require_c_parser
from tests.support.flows import write_udp_pcap

GCS = ("192.168.1.2", 40000)
VEHICLE = ("192.168.1.10", 14550)
PURE, NATIVE = {"MAVSCOPE_PURE": "1"}, {"MAVSCOPE_PURE": ""}


@pytest.fixture(scope="module")
def cparser() -> CParser:
    return require_c_parser()


def arms(rows: list[dict]) -> list[tuple[int, list[str]]]:
    """(record, note codes) of each COMMAND_LONG ARM (command 400, param1 1) with a good CRC shown."""
    return [(r["frame"], [n["code"] for n in r["notes"]]) for r in rows if r["msgname"] == "COMMAND_LONG"
            and r["crc_status"] == "ok" and r["fields"]["command"] == 400 and r["fields"]["param1"] == 1.0]


def both(cli, path: Path) -> list[dict]:  # type: ignore[no-untyped-def]
    """`read -T jsonl` on both engines, which must agree (MAVSCOPE_PURE=1 the reference)."""
    rows = cli.jsonl(path, environ=PURE)
    assert cli.jsonl(path, environ=NATIVE) == rows
    return rows


def half_datagrams() -> tuple[bytes, bytes]:
    a = arm()
    return a[:20], a[20:]


def test_the_vehicles_socket_reads_the_arm_whatever_address_its_halves_went_to(cli, tmp_path: Path,  # type: ignore[no-untyped-def]
                                                                                cparser: CParser) -> None:
    d1, d2 = half_datagrams()
    # The socket gets both datagrams, one after another: the C parser kept across them reads the ARM, ending in
    # the second (start -20); a parser reset at each datagram (a per-datagram reader) reads nothing
    assert cparser.frames([d1, d2], keep=True) == [set(), {(-20, len(arm()))}]
    assert cparser.frames([d1, d2]) == [set(), set()]
    hb = pmav.heartbeat(pmav.mav2())
    other = ("192.168.1.20", 14550)  # another host on the same port, whose datagram this socket does not get
    cases = {
        "subnet broadcast": [(GCS, VEHICLE, d1), (GCS, ("192.168.1.255", 14550), d2)],
        "limited broadcast": [(GCS, VEHICLE, d1), (GCS, ("255.255.255.255", 14550), d2)],
        "broadcast first": [(GCS, ("255.255.255.255", 14550), d1), (GCS, other, hb), (GCS, VEHICLE, d2)],
        "IPv4-mapped": [(GCS, VEHICLE, d1), (("::ffff:192.168.1.2", 40000), ("::ffff:192.168.1.10", 14550), d2)],
        "loopback pair": [(("127.0.0.1", 40000), ("127.0.0.1", 14550), d1), (("::1", 40000), ("::1", 14550), d2)],
        "dual stack": [(GCS, VEHICLE, d1), (("fe80::2", 40000), ("fe80::10", 14550), d2)],
        "other host between": [(GCS, VEHICLE, d1), (GCS, other, d1 + hb), (GCS, VEHICLE, d2)],
    }
    for name, packets in cases.items():
        rows = both(cli, write_udp_pcap(tmp_path / f"{name}.pcap", packets))
        last = len(packets)
        got = arms(rows)
        # the ARM is shown where it ends, in the datagram that completes it for the vehicle's socket
        assert [r for r, codes in got if "split-frame" in codes] == [last], (name, got)
        note = next(n["message"] for r in rows if r["frame"] == last for n in r["notes"] if n["code"] == "split-frame")
        # a pair the capture cannot tie to one host (fe80::10 and 192.168.1.10) is said to be a condition
        assert ("if " in note.split(",")[0]) == (name == "dual stack"), (name, note)
    status, out, _ = cli("commands", write_udp_pcap(tmp_path / "c.pcap", cases["subnet broadcast"]), environ=PURE)
    assert status == 0 and "ARM" in out.upper()
    # audit, the security command, says so: a command per-datagram tools never show (exit 1, the ARM's frame)
    for env in (PURE, NATIVE):
        doc = json.loads(cli("audit", tmp_path / "c.pcap", "--json", environ=env).out)
        split = [f["frames"] for f in doc["findings"] if f["code"] == "split-frame"]
        assert split == [[2]]


def test_a_flood_of_waiting_receivers_does_not_hide_the_arm_and_is_said(cli, tmp_path: Path,  # type: ignore[no-untyped-def]
                                                                        cparser: CParser) -> None:
    d1, d2 = half_datagrams()
    stub = b"\xfd\x09"  # the start of a frame: each flood datagram leaves its receiver in a frame
    # the vehicle's socket gets d1 and d2 only: the C parser kept across them reads the ARM
    assert cparser.frames([d1, d2], keep=True)[1] == {(-20, len(arm()))}
    floods = {
        # the reproducer: 256 other destinations (other ports), each left mid-frame
        "other ports": [(GCS, ("192.168.1.30", 20000 + i), stub) for i in range(256)],
        # other hosts on the vehicle's own port, past what a port holds
        "same port": [(GCS, (f"10.0.{i // 200}.{i % 200 + 1}", 14550), stub) for i in range(MAX_PER_PORT + 40)],
        # past what all ports hold together (after a good frame from GCS, whose datagrams are then MAVLink on
        # any port)
        "everywhere": [(GCS, ("10.1.0.1", 1), pmav.heartbeat(pmav.mav2())),
                       *((GCS, ("10.1.0.1", 1024 + i), stub) for i in range(MAX_STATES + 10))],
    }
    for name, flood in floods.items():
        packets = [(GCS, VEHICLE, d1), *flood, (GCS, VEHICLE, d2)]
        path = write_udp_pcap(tmp_path / f"{name}.pcap", packets)
        rows = cli.jsonl(path, environ=PURE)
        assert [r for r, codes in arms(rows) if "split-frame" in codes] == [len(packets)], name
        if name == "everywhere":
            assert cli.jsonl(path, environ=NATIVE) == rows
        status, out, _ = cli("audit", path, environ=PURE)
        if name == "other ports":  # nothing was given up: 256 states are far from the bounds
            assert "capacity" not in out
            continue
        # what was given up is an audit finding, with the records and bytes of each frame let go
        assert "capacity" in out, (name, out)
        _, _, out = cli("read", path, environ=PURE)  # (the flood's datagrams hold no frame: problems on stderr)
        assert "was let go in a frame of which 2 bytes had come, in record(s)" in out, name
        given = MAX_PER_PORT + 40 - (MAX_PER_PORT - 1) if name == "same port" else MAX_STATES + 10 - (MAX_STATES - 1)
        # the newest state goes (the flood's own), never the ARM's first half that came before it (the ARM
        # was shown above); each give-up is counted, the 1st, 2nd, 4th... said with the count so far
        assert f"({1 << (given.bit_length() - 1):,} given up so far" in out, (name, given)
        assert f"({(1 << given.bit_length()):,} given up so far" not in out, (name, given)


def flood_hosts(n: int) -> list[tuple[str, int]]:
    """`n` other hosts on the vehicle's port, none an address taken for a broadcast (last octet 1..100)."""
    return [(f"10.{i // 10000}.{i // 100 % 100}.{i % 100 + 1}", 14550) for i in range(n)]


def shown_as_built(rows: list[dict], record: int, built: bytes) -> bool:
    """The frame shown at `record` is `built` as pymavlink decodes it (independent of mavscope's decoding)."""
    from pymavlink.dialects.v20 import common

    m = common.MAVLink(None).decode(bytearray(built))
    hdr = m.get_header()
    return any(r["frame"] == record and r["msgname"] == m.get_type() and r["seq"] == hdr.seq
               and r["sysid"] == hdr.srcSystem and r["compid"] == hdr.srcComponent
               and r["crc"] == int.from_bytes(built[-2:], "little") and r["crc_status"] == "ok"
               and r["fields"]["command"] == m.command and r["fields"]["param1"] == m.param1 for r in rows)


def capacity(rows: list[dict]) -> str:
    """The `capacity` notes on the frames shown, one a line."""
    return "\n".join(n["message"] for r in rows for n in r["notes"] if n["code"] == "capacity")


def test_a_broadcast_half_outlives_a_flood_of_hosts_on_its_port(cli, tmp_path: Path,  # type: ignore[no-untyped-def]
                                                                 cparser: CParser) -> None:
    # The ARM's first 20 bytes to 255.255.255.255:14550, then clean HEARTBEATs to n other hosts on port 14550
    # (each reaches only its own host), then the rest to the vehicle. The vehicle's socket gets the broadcast
    # and the rest only: the C parser kept across them reads the ARM (its 44 bytes, ending in the second). The
    # hosts the HEARTBEATs reach go on from the broadcast's state (mavscope follows at most 64 a port and tells
    # at most 256 apart): the broadcast's state must outlive them (it was there before the flood).
    d1, d2 = half_datagrams()
    assert cparser.frames([d1, d2], keep=True) == [set(), {(-20, len(arm()))}]
    hb = pmav.heartbeat(pmav.mav2())
    for n in (10, 300, 10_000):
        packets = [(GCS, ("255.255.255.255", 14550), d1), *((GCS, h, hb) for h in flood_hosts(n)), (GCS, VEHICLE, d2)]
        path = write_udp_pcap(tmp_path / f"bcast{n}.pcap", packets)
        rows = both(cli, path)
        assert [r for r, codes in arms(rows) if "split-frame" in codes] == [len(packets)], n
        assert shown_as_built(rows, len(packets), arm()), n
        status, out, _ = cli("audit", path, environ=PURE)
        if n == 10:  # far from every bound: nothing given up
            assert "capacity" not in out, out
            continue
        # what was given up (the newest hosts' receivers, the newest hosts told apart) is an audit finding,
        # and each is said on its record
        assert "[warn] capacity" in out, (n, out)
        said = capacity(rows)
        assert "is no longer told apart from the hosts a broadcast to the port left in a frame" in said, n
        assert "the receiver at 10." in said and "was let go in a frame of which 41 bytes had come" in said, n
        assert "a broadcast to port 14550 left in a frame was let go" not in said


def test_a_host_forgotten_past_the_bound_is_read_from_each_state_it_may_be_in(cli, tmp_path: Path,  # type: ignore[no-untyped-def]
                                                                              cparser: CParser) -> None:
    # A broadcast leaves every receiver on port 14550 two bytes into a frame (the start of a 21-byte frame);
    # 318 HEARTBEATs to other hosts each end it there (CRC wrong, idle after), so each host is told apart from
    # those still in it, past the 256 a port holds. The vehicle gets a HEARTBEAT too, and one more host after
    # it: the vehicle is the host forgotten (the newest but the one just added), the 64th (318 + 2 - 256),
    # said. Then the ARM in two halves to the vehicle. The vehicle's socket gets the broadcast, its HEARTBEAT
    # and the two halves: the C parser kept across them reads the ARM in the last one.
    d1, d2 = half_datagrams()
    stub = b"\xfd\x09"
    hb = pmav.heartbeat(pmav.mav2())
    assert cparser.frames([stub, hb, d1, d2], keep=True)[3] == {(-20, len(arm()))}
    hosts = flood_hosts(319)
    packets = [(GCS, ("192.168.1.255", 14550), stub), *((GCS, h, hb) for h in hosts[:318]), (GCS, VEHICLE, hb),
               (GCS, hosts[318], hb), (GCS, VEHICLE, d1), (GCS, VEHICLE, d2)]
    path = write_udp_pcap(tmp_path / "forgotten.pcap", packets)
    rows = both(cli, path)
    assert [r for r, codes in arms(rows) if "split-frame" in codes] == [len(packets)]
    assert shown_as_built(rows, len(packets), arm())
    # read by the vehicle's own receiver (every datagram went to its address or a broadcast), not only by the
    # port's wildcard state, whose note would say the condition "if ... reach one receiving socket"
    note = next(n["message"] for r in rows if r["frame"] == len(packets) for n in r["notes"]
                if n["code"] == "split-frame")
    assert not note.startswith("if "), note
    assert "192.168.1.10:14550 is no longer told apart" in capacity(rows)
    assert "(64 given up so far, 64 hosts)" in capacity(rows)
