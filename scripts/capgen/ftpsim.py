"""Scripted exchanges for the object captures: a timeline of messages per side, some marked lost (they are
encoded, so their sender's MAVLink sequence number advances, but the capture never sees them), and an
MAVLink FTP client and server that build their packets with pymavlink's own `mavftp_op.FTP_OP`
(https://mavlink.io/en/services/ftp.html: a reply carries the request's sequence number + 1 and its
opcode in `req_opcode`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from random import Random
from typing import Any

from pymavlink.mavftp_op import FTP_OP

from .constants import BASE_TIME_US, LINKTYPE_ETHERNET, LOOPBACK_V4
from .frames import Endpoint, Send
from .packets import Pkt, UdpFlow
from .summary import summarize_packets
from .writers import write_pcap

ACK, NAK = 128, 129
EOF, FILE_NOT_FOUND, FAIL = 6, 10, 1
Build = Callable[[Any], Any]


@dataclass
class Entry:
    t_us: int
    side: str
    build: Build
    lost: bool = False
    record: int | None = None  # the capture record number it ended up in (None when lost)


@dataclass
class Script:
    """Messages in time order; `t_us` advances with each one sent."""

    rng: Random
    t_us: int = 1_000_000
    entries: list[Entry] = field(default_factory=list)

    def send(self, side: str, build: Build, gap_us: int = 4_000, lost: bool = False) -> Entry:
        self.t_us += gap_us + self.rng.randint(0, 499)
        e = Entry(self.t_us, side, build, lost)
        self.entries.append(e)
        return e

    def at(self, t_us: int) -> None:
        self.t_us = max(self.t_us, t_us)


def ftp_message(target: tuple[int, int], op: FTP_OP) -> Build:
    payload = bytes(op.pack()).ljust(251, b"\0")
    return lambda mav: mav.file_transfer_protocol_encode(0, target[0], target[1], payload)


class FtpClient:
    def __init__(self, script: Script, side: str, me: tuple[int, int], server: tuple[int, int],
                 server_side: str = "vehicle") -> None:
        self.script, self.side, self.me, self.server, self.server_side = script, side, me, server, server_side
        self.seq = 0

    def request(self, opcode: int, *, session: int = 0, size: int | None = None, offset: int = 0,
                data: bytes = b"", lost: bool = False, gap_us: int = 5_000) -> FTP_OP:
        op = FTP_OP(self.seq, session, opcode, len(data) if size is None else size, 0, 0, offset, bytearray(data))
        self.seq = (self.seq + 1) % 65_536
        self.script.send(self.side, ftp_message(self.server, op), gap_us, lost)
        return op

    def again(self, op: FTP_OP, *, lost: bool = False, gap_us: int = 1_000_000) -> None:
        """The same request once more (its answer did not come): same sequence number, as pymavlink retries."""
        self.script.send(self.side, ftp_message(self.server, op), gap_us, lost)

    def reply(self, req: FTP_OP, opcode: int = ACK, *, data: bytes = b"", offset: int | None = None,
              session: int | None = None, burst_complete: int = 0, seq: int | None = None, lost: bool = False,
              gap_us: int = 3_000) -> FTP_OP:
        """The server's answer to `req`."""
        op = FTP_OP(req.seq + 1 if seq is None else seq, req.session if session is None else session, opcode,
                    len(data), req.opcode, burst_complete, req.offset if offset is None else offset,
                    bytearray(data))
        self.script.send(self.server_side, ftp_message(self.me, op), gap_us, lost)
        return op

    def nak(self, req: FTP_OP, error: int, **kw: Any) -> FTP_OP:
        return self.reply(req, NAK, data=bytes([error]), **kw)


def write_capture(path: Any, script: Script, endpoints: dict[str, Endpoint], flows: dict[str, tuple[UdpFlow, str]],
                  ) -> tuple[dict[str, Any], list[Pkt]]:
    """Encode every entry in time order (lost ones too: sequence numbers advance), write the others as one
    UDP datagram each, and number the records they land in. `flows`: side -> (flow, its side in the flow)."""
    pkts: list[Pkt] = []
    for e in sorted(script.entries, key=lambda e: e.t_us):
        ep = endpoints[e.side]
        frame = ep.pack(e.build(ep.mav), BASE_TIME_US + e.t_us)
        if e.lost:
            continue
        flow, as_side = flows[e.side]
        pkts.append(flow.packet(Send(e.t_us, as_side, [frame])))
        e.record = len(pkts)
    offsets = write_pcap(path, LINKTYPE_ETHERNET, pkts)
    return summarize_packets("pcap", [LINKTYPE_ETHERNET], pkts, offsets), pkts


def udp_flows(rng: Random, gcs_port: int, vehicle_port: int = 14_555) -> UdpFlow:
    return UdpFlow({"vehicle": (LOOPBACK_V4, vehicle_port), "gcs": (LOOPBACK_V4, gcs_port)}, rng)
