"""Hostile input the pipeline must survive (issue: hostile captures): junk where MAVLink is expected, a
low-order X25519 key. Each input is built here; the expectation is what a correct tool must report."""

from __future__ import annotations

from pathlib import Path

from scripts.capgen.encode import encode_frame
from scripts.capgen.kex import KEY_EXCHANGE_MSGID, key_exchange_crc_extra, key_exchange_payload
from tests.conftest import ROOT, Cli
from tests.support import flows
from tests.support.builders import write_udp_pcap

HEARTBEAT = flows.Sender(1, 1).pack(flows.heartbeat())


def pcap(tmp: Path, payloads: list[bytes], port: int = 14550, name: str = "c.pcap") -> str:
    """Ethernet/IPv4/UDP records 127.0.0.1:`port` -> 127.0.0.1:`port`, one per payload, a second apart."""
    lo = ("127.0.0.1", port)
    return str(write_udp_pcap(tmp / name, [(lo, lo, data) for data in payloads], t0=1_773_482_400))


def test_a_datagram_of_junk_on_a_mavlink_port(cli: Cli, tmp_path: Path) -> None:
    """"hello" to 14550 once raised IndexError in every command: now a skipped-bytes note."""
    path = pcap(tmp_path, [HEARTBEAT, b"hello", HEARTBEAT])
    status, out, err = cli("read", path)
    assert status == 0 and out.count("HEARTBEAT") == 2
    assert "record 2" in err and "5 bytes that are not MAVLink skipped" in err
    for command in ("stats", "mission", "commands", "timeline", "audit", "events", "track"):
        status, _, err = cli(command, path, "--json")
        assert status in (0, 1) and "Traceback" not in err, command


def test_a_frame_followed_by_two_stray_bytes(cli: Cli, tmp_path: Path) -> None:
    """The frame before the junk is shown and the junk is a note, on any port."""
    path = pcap(tmp_path, [HEARTBEAT + b"\xfd\x01"], port=40000)
    status, out, err = cli("read", path, "-T", "jsonl")
    assert status == 0 and out.count('"HEARTBEAT"') == 1 and "2 bytes that are not MAVLink skipped" in err


def test_a_low_order_x25519_key_is_a_note(cli: Cli, tmp_path: Path) -> None:
    """A MAVSCOPE_KEY_EXCHANGE with an all-zero public key once raised ValueError under --ecdh-private."""
    extra = key_exchange_crc_extra(ROOT / "dissectors" / "mavscope.xml")
    payload = key_exchange_payload(1_000_000, 1, 1, 1, bytes(32))
    frame = encode_frame(KEY_EXCHANGE_MSGID, payload, extra, sysid=255, compid=190)
    path = pcap(tmp_path, [HEARTBEAT, frame, HEARTBEAT])
    rows = cli.jsonl(path, "--ecdh-private", "hex:" + "11" * 32)
    notes = [n for r in rows for n in r["notes"] if n["code"] == "key-exchange"]
    assert len(rows) == 3 and len(notes) == 1 and "low-order point" in notes[0]["message"]
