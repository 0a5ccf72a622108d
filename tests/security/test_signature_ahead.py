"""`signature-ahead`: a signing stream that starts far ahead of every other stream (the future-timestamp
attack). On the real attack capture the expectation is derived here without mavscope: the pcap records read
by hand (global header, record headers, Ethernet/IPv4/UDP) and each datagram parsed by pymavlink, whose
frames carry the signature block (link id, 48-bit timestamp in 10 us units since 2015-01-01) in clear."""

from __future__ import annotations

import json
import struct
from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as apm

from mavscope.mavlink.frame import CrcStatus, Frame, Signature, new_frame
from mavscope.security.audit import AHEAD_S, Audit, ahead_findings
from tests.conftest import Cli

ATTACK = "ap_sitl_attack1_signed_knownkey.pcap"
SIGNING_EPOCH = 1_420_070_400  # 2015-01-01T00:00:00Z, the MAVLink 2 signing timestamp's origin (by the spec)


def _stream_starts(path: Path) -> dict[tuple[int, int, int], tuple[int, float]]:
    """(sysid, compid, link) -> (record number, signature time - capture time) of each signing stream's first
    frame, by hand and pymavlink."""
    data = path.read_bytes()
    assert struct.unpack_from("<I", data)[0] == 0xA1B2C3D4 and struct.unpack_from("<I", data, 20)[0] == 1  # Ethernet
    mav = apm.MAVLink(None)
    mav.robust_parsing = True
    starts: dict[tuple[int, int, int], tuple[int, float]] = {}
    pos, record = 24, 0
    while pos + 16 <= len(data):
        sec, usec, incl, _ = struct.unpack_from("<IIII", data, pos)
        pkt = data[pos + 16 : pos + 16 + incl]
        pos += 16 + incl
        record += 1
        ip = pkt[14:]
        udp = ip[(ip[0] & 15) * 4 :]
        for msg in mav.parse_buffer(udp[8:]) or []:
            buf = bytes(msg.get_msgbuf())
            if buf[0] != 0xFD or not buf[2] & 1:  # MAVLink 2 with MAVLINK_IFLAG_SIGNED (pymavlink's get_signed()
                continue  # is set only where it verified a signature)
            link, stamp = buf[-13], int.from_bytes(buf[-12:-6], "little")
            key = (msg.get_srcSystem(), msg.get_srcComponent(), link)
            starts.setdefault(key, (record, SIGNING_EPOCH + stamp / 100_000 - (sec + usec / 1e6)))
    return starts


def test_the_future_timestamp_attack_is_found_without_a_key(real_captures: Path, cli: Cli) -> None:
    starts = _stream_starts(real_captures / ATTACK)
    ahead = {s: v for s, v in starts.items()
             if v[1] > 60 and all(v[1] - k > AHEAD_S for t, (_, k) in starts.items() if t != s)}
    assert len(starts) >= 2 and len(ahead) == 1  # the injected stream, a day ahead of the vehicle's
    (stream, (record, skew)), = ahead.items()
    status, out, _ = cli("audit", str(real_captures / ATTACK), "--json")
    found = [f for f in json.loads(out)["findings"] if f["code"] == "signature-ahead"]
    assert status == 1 and len(found) == 1
    assert found[0]["frames"] == [record] and found[0]["severity"] == "warn"
    message = found[0]["message"]
    assert message.startswith(f"{stream[0]}/{stream[1]} signature link {stream[2]}:") and f"{skew:+,.0f} s" in message


def _signed(record: int, sysid: int, link: int, capture: float, ahead: float) -> Frame:
    stamp = round((capture + ahead - SIGNING_EPOCH) * 100_000)
    return new_frame(record, 1, capture, "udp", None, None, 0, bytes(20), 2, 0, 1, 0, 0, sysid, 1, 0, 0,
                     CrcStatus.OK, None, Signature(link, stamp, bytes(6)), (), None)


def _ahead(*frames: Frame) -> list[tuple[str, tuple[int, ...]]]:
    a = Audit()
    for f in frames:
        a.add(f)
    return [(f.code, f.frames) for f in ahead_findings(a.targets.frames)]


def test_only_a_stream_far_ahead_of_every_other_is_named() -> None:
    t = 1_780_000_000.0
    assert _ahead(_signed(1, 1, 0, t, -5), _signed(2, 255, 1, t + 1, 86_398)) == [("signature-ahead", (2,))]
    assert _ahead(_signed(1, 1, 0, t, -5), _signed(2, 255, 1, t + 1, 30)) == []  # seconds apart: clocks
    assert _ahead(_signed(1, 255, 1, t, 86_398)) == []  # one stream: the capture clock may be the wrong one
    assert _ahead(_signed(1, 1, 0, t, 86_000), _signed(2, 255, 1, t, 86_398)) == []  # a wrong capture clock
    # the stream's first signed frame decides, not a later one
    assert _ahead(_signed(1, 1, 0, t, 0), _signed(2, 255, 1, t, 0), _signed(3, 255, 1, t, 90_000)) == []
