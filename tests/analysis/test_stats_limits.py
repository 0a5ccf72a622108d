"""The rows `stats` follows are bounded (stop 25): a capture can name a new (sender, message) stream, a
new pair of endpoints or a new message id in every frame. 200,000 such frames (random senders and ids)
held 590 MB in `stats`, 400,000 more still. Frames beyond the limits count in the totals, their link, and
as unfollowed (JSON and a text line); the sequence findings name at most MAX_NAMED messages in all.

The limits are lowered here; each capture is built with pymavlink and the expected counts follow from
how it was built. The pure path runs (the native one hands captures past its own, lower caps to it).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as v2

from mavscope.analysis import expert, stats
from tests.conftest import Cli
from tests.support import flows
from tests.support.builders import write_udp_pcap

PURE = {"MAVSCOPE_PURE": "1"}


def test_streams_past_the_limit_count_in_totals_links_and_as_unfollowed(
        cli: Cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """One sender sends HEARTBEAT, SYS_STATUS, then ATTITUDE, GPS_RAW_INT x2, then HEARTBEAT again: with
    two streams followed, the last three message types are 3 frames not in the Messages table."""
    monkeypatch.setattr(stats, "MAX_STREAMS", 2)
    s = flows.Sender(1, 1)
    gps = v2.MAVLink_gps_raw_int_message(0, 0, 0, 0, 0, 0, 0, 0, 0, 0)
    msgs = [flows.heartbeat(), v2.MAVLink_sys_status_message(0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0),
            v2.MAVLink_attitude_message(0, 0, 0, 0, 0, 0, 0), gps, gps, flows.heartbeat()]
    path = flows.write_tlog(tmp_path, [(flows.T0 + i, s.pack(m)) for i, m in enumerate(msgs)])
    doc = cli.json("stats", path, environ=PURE)
    assert [(m["msgname"], m["count"]) for m in doc["messages"]] == [("HEARTBEAT", 2), ("SYS_STATUS", 1)]
    assert doc["links"][0]["received"] == 6 and doc["links"][0]["lost"] == 0
    assert doc["totals"]["frames"] == 6 and doc["totals"]["unfollowed_stream_frames"] == 3
    assert doc["totals"]["unfollowed_conversation_frames"] == 0
    status, out, _ = cli("stats", path, environ=PURE)
    assert status == 0 and "3 frames are not in the Messages table: their (sender, message) streams came after " \
                          "the first 2" in " ".join(out.split())


def udp_pcap(tmp: Path, datagrams: list[tuple[int, bytes]]) -> str:
    """Ethernet/IPv4/UDP records 127.0.0.1:port -> 127.0.0.1:14550, one per (port, payload), a second apart."""
    packets = [(("127.0.0.1", port), ("127.0.0.1", 14550), data) for port, data in datagrams]
    return str(write_udp_pcap(tmp / "c.pcap", packets, t0=1_773_482_400))


def test_conversations_past_the_limit_are_unfollowed(cli: Cli, tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """HEARTBEATs from ports 40001, 40002, 40003, 40001: with one conversation followed, two frames."""
    monkeypatch.setattr(stats, "MAX_CONVERSATIONS", 1)
    s = flows.Sender(1, 1)
    path = udp_pcap(tmp_path, [(port, s.pack(flows.heartbeat())) for port in (40001, 40002, 40003, 40001)])
    doc = cli.json("stats", path, environ=PURE)
    assert [(c["a"], c["frames"]) for c in doc["conversations"]] == [("127.0.0.1:14550", 2)]
    assert doc["conversations"][0]["b"] == "127.0.0.1:40001"
    assert doc["totals"]["unfollowed_conversation_frames"] == 2 and doc["totals"]["frames"] == 4
    assert doc["messages"][0]["count"] == 4 and doc["links"][0]["received"] == 4


def test_sequence_findings_name_at_most_max_named_messages(cli: Cli, tmp_path: Path,
                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """Sender 1/1 sends HEARTBEAT, ATTITUDE, SYS_STATUS (seq 0, 1, 2), each frame twice: 3 duplicates of
    3 messages. With two names kept the finding says "(ATTITUDE, HEARTBEAT and more)" (equal counts: by
    name); with the real limit it names all three."""
    monkeypatch.setattr(expert, "MAX_NAMED", 2)
    s = flows.Sender(1, 1)
    msgs = [flows.heartbeat(), v2.MAVLink_attitude_message(0, 0, 0, 0, 0, 0, 0),
            v2.MAVLink_sys_status_message(0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0)]
    frames = [s.pack(m) for m in msgs]
    path = flows.write_tlog(tmp_path, [(flows.T0 + i, frames[i // 2]) for i in range(6)])

    def said() -> list[str]:
        doc = cli.json("stats", path, environ=PURE)
        return [f["message"] for f in doc["findings"] if f["code"].startswith("seq-")]

    assert said() == ["link 1/1: 3 frames repeat a sequence number already seen on their channel "
                      "(ATTITUDE, HEARTBEAT and more)"]
    monkeypatch.setattr(expert, "MAX_NAMED", 1 << 18)
    assert said() == ["link 1/1: 3 frames repeat a sequence number already seen on their channel "
                      "(ATTITUDE, HEARTBEAT, SYS_STATUS)"]
