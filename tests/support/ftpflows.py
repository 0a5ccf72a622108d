"""MAVLink FTP, log and image exchanges built with pymavlink (FTP packets packed by pymavlink's own
`mavftp_op.FTP_OP`), written as tlogs, for the object and parameter tests. What a test builds is its
expected answer; mavscope's output is never used to make one."""

from __future__ import annotations

from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as v2
from pymavlink.mavftp_op import FTP_OP

from mavscope.capture.detect import open_capture
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.pipeline.dissect import Dissector
from tests.support.flows import T0, Sender, tlog

TERMINATE, RESET, LIST, OPEN_RO, READ, CREATE, WRITE, REMOVE = 1, 2, 3, 4, 5, 6, 7, 8
OPEN_WO, CRC32, BURST, ACK, NAK = 11, 14, 15, 128, 129
EOF, FAIL, FILE_NOT_FOUND = 6, 1, 10
VEHICLE, GCS = (1, 1), (255, 190)


class Flow:
    """A GCS and a vehicle exchanging frames, one tlog entry each, 10 ms apart."""

    def __init__(self, gcs: tuple[int, int] = GCS, vehicle: tuple[int, int] = VEHICLE) -> None:
        self.gcs_addr, self.vehicle_addr = gcs, vehicle
        self.senders = {gcs: Sender(*gcs), vehicle: Sender(*vehicle)}
        self.entries: list[tuple[float, bytes]] = []
        self.t = T0
        self.seq = 0  # the GCS's FTP sequence number

    def sender(self, addr: tuple[int, int]) -> Sender:
        if addr not in self.senders:
            self.senders[addr] = Sender(*addr)
        return self.senders[addr]

    def send(self, addr: tuple[int, int], msg: object, dt: float = 0.01) -> int:
        """Add a frame from `addr`; returns its record number in the tlog."""
        self.t += dt
        self.entries.append((self.t, self.sender(addr).pack(msg)))
        return len(self.entries)

    def ftp(self, src: tuple[int, int], dst: tuple[int, int], op: FTP_OP) -> int:
        payload = list(bytes(op.pack()).ljust(251, b"\0")[:251])
        return self.send(src, v2.MAVLink_file_transfer_protocol_message(0, dst[0], dst[1], payload))

    def request(self, opcode: int, *, session: int = 0, size: int | None = None, offset: int = 0,
                data: bytes = b"", seq: int | None = None, src: tuple[int, int] | None = None,
                dst: tuple[int, int] | None = None) -> FTP_OP:
        if seq is None:
            seq = self.seq
            self.seq = (self.seq + 1) % 65_536
        op = FTP_OP(seq, session, opcode, len(data) if size is None else size, 0, 0, offset, bytearray(data))
        self.ftp(src or self.gcs_addr, dst or self.vehicle_addr, op)
        return op

    def reply(self, req: FTP_OP, opcode: int = ACK, *, data: bytes = b"", offset: int | None = None,
              session: int | None = None, burst_complete: int = 0, seq: int | None = None,
              src: tuple[int, int] | None = None, dst: tuple[int, int] | None = None) -> int:
        op = FTP_OP(req.seq + 1 if seq is None else seq, req.session if session is None else session, opcode,
                    len(data), req.opcode, burst_complete, req.offset if offset is None else offset, bytearray(data))
        return self.ftp(src or self.vehicle_addr, dst or self.gcs_addr, op)

    def nak(self, req: FTP_OP, error: int, **kw: object) -> int:
        return self.reply(req, NAK, data=bytes([error]), **kw)  # type: ignore[arg-type]

    def write(self, tmp: Path, name: str = "ftp.tlog") -> Path:
        path = tmp / name
        path.write_bytes(tlog(self.entries))
        return path


def frames_of(path: Path, dialect: Dialect) -> list[Frame]:
    with open_capture(path) as reader:
        return [f for f in Dissector(dialect).run(reader) if isinstance(f, Frame)]


def read_file(flow: Flow, path: str, data: bytes, session: int = 0, *, chunk: int = 239,
              skip: frozenset[int] = frozenset(), eof: bool = True, announce: int | None = None) -> None:
    """OpenFileRO, then one ReadFile per `chunk` (their ACKs; those numbered in `skip` are not sent), the
    EOF NAK, TerminateSession."""
    open_req = flow.request(OPEN_RO, data=path.encode())
    size = len(data) if announce is None else announce
    flow.reply(open_req, session=session, data=size.to_bytes(4, "little"))
    for n, offset in enumerate(range(0, len(data), chunk)):
        req = flow.request(READ, session=session, size=chunk, offset=offset)
        if n not in skip:
            flow.reply(req, data=data[offset : offset + chunk])
    if eof:
        req = flow.request(READ, session=session, size=chunk, offset=len(data))
        flow.nak(req, EOF)
    term = flow.request(TERMINATE, session=session)
    flow.reply(term)
