"""MAVLink FTP on a real capture: ArduPlane SITL serving `@PARAM/param.pck` to MAVProxy and Mission Planner
(497 FILE_TRANSFER_PROTOCOL frames). pymavlink reads the tlog on its own and the test decodes each FTP
header with `struct`; mavscope's fields and filters must agree frame by frame. The counts per sender and
opcode, and the NAKs, are written out from that reading (pymavlink and struct, no mavscope), and
`test_counts_per_sender_and_opcode` and `test_naks_as_struct_reads_them` derive them again."""

from __future__ import annotations

import struct
from collections import Counter
from pathlib import Path
from typing import NamedTuple

import pytest
from pymavlink import mavutil

from mavscope.capture.detect import open_capture
from mavscope.fields.registry import MISSING, field
from mavscope.filter import compile_filter
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.pipeline.dissect import Dissector

NAME = "ap_plane_sitl_mission3types_ftp_mp_mavproxy.tlog"
OPNAMES = {1: "TerminateSession", 2: "ResetSessions", 4: "OpenFileRO", 15: "BurstReadFile", 128: "ACK", 129: "NAK"}
PATH_OPCODES = {3, 4, 6, 8, 9, 10, 11, 12, 13, 14}
BY_SENDER_AND_OPCODE = {
    "1/1 ACK(BurstReadFile)": 473, "1/1 ACK(OpenFileRO)": 3, "1/1 ACK(ResetSessions)": 1,
    "1/1 ACK(TerminateSession)": 4, "1/1 NAK(BurstReadFile)": 3, "1/1 NAK(OpenFileRO)": 1,
    "255/190 BurstReadFile": 1, "255/190 OpenFileRO": 2, "255/190 ResetSessions": 1,
    "255/230 BurstReadFile": 2, "255/230 OpenFileRO": 2, "255/230 TerminateSession": 4,
}
NAKS = {338: (1, 15, 16169, 6), 340: (0, 4, 0, 4), 668: (3, 15, 16169, 6), 2520: (0, 15, 15926, 6)}  # frame: ...


class Ref(NamedTuple):
    """One FTP packet as pymavlink and struct read it."""

    sender: str
    seq: int
    session: int
    opcode: int
    size: int
    req_opcode: int
    offset: int
    data: bytes
    path: str | None
    error: int | None


def reference(path: Path) -> list[Ref]:
    conn = mavutil.mavlink_connection(str(path), dialect="ardupilotmega")
    out = []
    while (msg := conn.recv_match(type="FILE_TRANSFER_PROTOCOL")) is not None:
        payload = bytes(msg.payload)
        seq, session, opcode, size, req, _burst, _pad, offset = struct.unpack_from("<HBBBBBBI", payload)
        data = payload[12 : 12 + min(size, 239)]
        path_ = data.split(b"\0")[0].decode() if opcode in PATH_OPCODES else None
        error = data[0] if opcode == 129 and size else None
        out.append(Ref(f"{msg.get_srcSystem()}/{msg.get_srcComponent()}", seq, session, opcode, size, req, offset,
                       data, path_, error))
    return out


@pytest.fixture(scope="module")
def capture(real_captures: Path, dialect: Dialect) -> tuple[list[Frame], list[Ref]]:
    path = real_captures / NAME
    if not path.is_file():
        pytest.skip(f"{path} is absent")
    with open_capture(path) as reader:
        frames = [f for f in Dissector(dialect).run(reader)
                  if isinstance(f, Frame) and f.msgname == "FILE_TRANSFER_PROTOCOL"]
    return frames, reference(path)


def test_fields_agree_with_struct(capture: tuple[list[Frame], list[Ref]]) -> None:
    frames, refs = capture
    assert len(frames) == len(refs) == 497
    for f, ref in zip(frames, refs, strict=True):
        assert f"{f.sysid}/{f.compid}" == ref.sender
        got = {name: field(f"ftp.{name}").get(f) for name in ("seq", "session", "opcode", "size", "req_opcode",
                                                               "offset")}
        assert got == {"seq": ref.seq, "session": ref.session, "opcode": ref.opcode, "size": ref.size,
                       "req_opcode": ref.req_opcode, "offset": ref.offset}, f.number
        assert field("ftp.path").get(f) == (MISSING if ref.path is None else ref.path)
        assert field("ftp.error").get(f) == (MISSING if ref.error is None else ref.error)
        if ref.opcode == 128 and ref.req_opcode == 15:  # the file's bytes
            assert field("ftp.data").get(f) == ref.data
        assert field("ftp.malformed").get(f) is MISSING


def test_counts_per_sender_and_opcode(capture: tuple[list[Frame], list[Ref]]) -> None:
    _frames, refs = capture
    seen = Counter(f"{r.sender} {OPNAMES[r.opcode]}" + (f"({OPNAMES[r.req_opcode]})" if r.opcode >= 128 else "")
                   for r in refs)
    assert seen == BY_SENDER_AND_OPCODE
    assert {r.path for r in refs if r.path} == {"@PARAM/param.pck", "@PARAM/param.pck?withdefaults=1"}


@pytest.mark.parametrize("text, select", [
    ("ftp.opcode == OpenFileRO", lambda r: r.opcode == 4),
    ("ftp.opcode == NAK", lambda r: r.opcode == 129),
    ("ftp.req_opcode == BurstReadFile && ftp.opcode == ACK", lambda r: r.opcode == 128 and r.req_opcode == 15),
    ('ftp.path contains "param.pck"', lambda r: r.path is not None and "param.pck" in r.path),
    ('ftp.path == "@PARAM/param.pck"', lambda r: r.path == "@PARAM/param.pck"),
    ("ftp.error == EOF", lambda r: r.error == 6),
    ("ftp.error == InvalidSession", lambda r: r.error == 4),
    ("ftp.session == 3", lambda r: r.session == 3),
    ("ftp.offset >= 16000", lambda r: r.offset >= 16000),
])
def test_filters_select_what_struct_says(capture: tuple[list[Frame], list[Ref]], dialect: Dialect, text: str,
                                         select) -> None:  # type: ignore[no-untyped-def]
    frames, refs = capture
    flt = compile_filter(text, dialect)
    assert [f.number for f in frames if flt.matches(f)] == [f.number for f, r in zip(frames, refs) if select(r)]


def test_naks(capture: tuple[list[Frame], list[Ref]], dialect: Dialect) -> None:
    frames, _refs = capture
    flt = compile_filter("ftp.opcode == NAK", dialect)
    naks = {f.record: tuple(field(n).get(f) for n in ("ftp.session", "ftp.req_opcode", "ftp.offset", "ftp.error"))
            for f in frames if flt.matches(f)}
    assert naks == NAKS


def test_naks_as_struct_reads_them(capture: tuple[list[Frame], list[Ref]]) -> None:
    frames, refs = capture
    assert {f.record: (r.session, r.req_opcode, r.offset, r.error) for f, r in zip(frames, refs)
            if r.opcode == 129} == NAKS
