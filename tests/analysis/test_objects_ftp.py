"""MAVLink FTP objects rebuilt from exchanges pymavlink builds (tests/support/ftpflows.py): each test says
what it sent, which is what it expects back (sizes, SHA-256 of the bytes it put in, gaps where it left a
packet out), never what mavscope said before."""

from __future__ import annotations

import hashlib
from pathlib import Path

from mavscope.analysis.objects import FTP_LIST, FTP_READ, FTP_WRITE, ObjectLog, analyse
from mavscope.mavlink.dialect import Dialect
from tests.support.ftpflows import (
    ACK,
    BURST,
    CRC32,
    CREATE,
    EOF,
    FAIL,
    FILE_NOT_FOUND,
    LIST,
    OPEN_RO,
    READ,
    REMOVE,
    RESET,
    TERMINATE,
    WRITE,
    Flow,
    frames_of,
    read_file,
)

DATA = bytes(range(256)) * 4 + b"tail"  # 1028 bytes


def run(flow: Flow, tmp_path: Path, dialect: Dialect) -> ObjectLog:
    return analyse(frames_of(flow.write(tmp_path), dialect), dialect)


def sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def test_a_read_with_read_file(tmp_path: Path, dialect: Dialect) -> None:
    flow = Flow()
    read_file(flow, "/APM/a.bin", DATA, session=2)
    log = run(flow, tmp_path, dialect)
    [obj] = log.objects
    assert (obj.kind, obj.path, obj.direction, obj.sender, obj.receiver) == (FTP_READ, "/APM/a.bin", "download",
                                                                             (1, 1), (255, 190))
    assert (obj.size, obj.sha256, obj.complete, obj.gaps, obj.data) == (len(DATA), sha(DATA), True, (), DATA)
    assert obj.details["session"] == 2 and obj.details["eof_offset"] == len(DATA)
    n_reads = -(-len(DATA) // 239)
    # open + ACK, n reads + ACKs, the EOF read + NAK, terminate + ACK
    assert obj.frame_count == 2 + 2 * n_reads + 2 + 2
    assert dict(obj.signatures["1/1"]) == {"unsigned": 3 + n_reads}  # the ACKs, the EOF NAK, the last ACK
    assert not log.findings


def test_out_of_order_duplicate_and_conflicting_bytes(tmp_path: Path, dialect: Dialect) -> None:
    flow = Flow()
    req = flow.request(OPEN_RO, data=b"/f")
    flow.reply(req, session=0, data=(300).to_bytes(4, "little"))
    burst = flow.request(BURST, size=100)
    flow.reply(burst, data=DATA[200:300], offset=200, seq=burst.seq + 1)  # out of order
    flow.reply(burst, data=DATA[0:100], offset=0, seq=burst.seq + 2)
    flow.reply(burst, data=DATA[0:100], offset=0, seq=burst.seq + 3)  # the same again: 100 duplicate bytes
    forged = bytearray(DATA[100:200])
    flow.reply(burst, data=DATA[100:200], offset=100, seq=burst.seq + 4)
    forged[0:5] = b"EVIL!"
    flow.reply(burst, data=bytes(forged), offset=100, seq=burst.seq + 5, burst_complete=1)  # 5 bytes differ
    flow.nak(flow.request(BURST, size=100, offset=300), EOF, offset=300)
    log = run(flow, tmp_path, dialect)
    [obj] = log.objects
    assert obj.data == DATA[:300] and obj.complete  # the first copy of every byte kept
    assert (obj.duplicate_bytes, obj.conflict_bytes) == (195, 5)
    assert [f.code for f in log.findings] == ["object-conflict"]


def test_lost_packet_stays_a_gap_and_announced_size_is_not_the_end(tmp_path: Path, dialect: Dialect) -> None:
    flow = Flow()
    read_file(flow, "@PARAM/param.pck", DATA, skip=frozenset({1}), announce=2000)  # ArduPilot over-announces
    [obj] = run(flow, tmp_path, dialect).objects
    assert obj.size == len(DATA) and obj.announced_size == 2000  # the EOF NAK's offset is the end
    assert obj.gaps == ((239, 478),) and not obj.complete and obj.end_known
    assert obj.data == DATA[:239] + bytes(239) + DATA[478:]
    assert obj.file == "0001-@PARAM_param.pck"


def test_without_eof_the_announced_size_ends_a_read(tmp_path: Path, dialect: Dialect) -> None:
    flow = Flow()
    read_file(flow, "/x", DATA, eof=False)  # PX4's client stops at the size the open announced
    [obj] = run(flow, tmp_path, dialect).objects
    assert (obj.size, obj.complete, obj.end_known) == (len(DATA), True, True)
    flow = Flow()
    read_file(flow, "/x", DATA, eof=False, skip=frozenset({4}))  # the last packet lost, no EOF
    [obj] = run(flow, tmp_path, dialect).objects
    assert (obj.size, obj.complete, obj.end_known, obj.gaps) == (len(DATA), False, False, ((956, 1028),))


def test_an_upload_with_a_retried_write_and_a_refused_one(tmp_path: Path, dialect: Dialect) -> None:
    flow = Flow()
    create = flow.request(CREATE, data=b"/APM/scripts/x.lua")
    flow.reply(create, session=1)
    for n, offset in enumerate(range(0, len(DATA), 200)):
        w = flow.request(WRITE, session=1, offset=offset, data=DATA[offset : offset + 200])
        if n == 1:  # its ACK was lost: the client sends the same request again
            flow.request(WRITE, session=1, offset=offset, data=DATA[offset : offset + 200], seq=w.seq)
        flow.reply(w)
    term = flow.request(TERMINATE, session=1)
    flow.reply(term)
    log = run(flow, tmp_path, dialect)
    [obj] = log.objects
    assert (obj.kind, obj.direction, obj.sender, obj.receiver) == (FTP_WRITE, "upload", (255, 190), (1, 1))
    assert (obj.size, obj.sha256, obj.complete) == (len(DATA), sha(DATA), True)
    assert obj.details["writes"] == 7 and obj.details["rewrites"] == 1  # 6 blocks, one sent twice
    assert obj.duplicate_bytes == 200
    assert {f.code for f in log.findings} == {"ftp-upload", "script-upload"}

    flow = Flow()
    create = flow.request(CREATE, data=b"/data.bin")
    flow.reply(create, session=0)
    w = flow.request(WRITE, offset=0, data=b"x" * 100)
    flow.nak(w, FAIL)  # refused: the bytes are carried but never acknowledged
    [obj] = run(flow, tmp_path, dialect).objects
    assert obj.size == 100 and not obj.complete
    assert obj.details["refused_writes"] == 1 and obj.details["unacknowledged"] == [[0, 100]]


def test_listing_with_a_missing_entry_and_operations(tmp_path: Path, dialect: Dialect) -> None:
    flow = Flow()
    first = flow.request(LIST, data=b"/APM")
    flow.reply(first, data=b"Fa.txt\t10\0Dlogs\0")
    second = flow.request(LIST, data=b"/APM", offset=2)  # its ACK (entries 2 and 3) never comes
    third = flow.request(LIST, data=b"/APM", offset=4)
    flow.reply(third, data=b"Fz.bin\t7\0")
    flow.nak(flow.request(LIST, data=b"/APM", offset=5), EOF)
    del second
    crc = flow.request(CRC32, data=b"/APM/a.txt")
    flow.reply(crc, data=(0xDEADBEEF).to_bytes(4, "little"))
    rm = flow.request(REMOVE, data=b"/APM/../etc/passwd")
    flow.nak(rm, FILE_NOT_FOUND)
    refused = flow.request(OPEN_RO, data=b"/nope")
    flow.nak(refused, FILE_NOT_FOUND)
    log = run(flow, tmp_path, dialect)
    [obj] = log.objects
    assert (obj.kind, obj.path, obj.gap_unit, obj.gaps, obj.complete) == (FTP_LIST, "/APM", "entries", ((2, 4),),
                                                                          False)
    assert [(e["index"], e["type"], e["name"], e["size"]) for e in obj.details["entries"]] == [
        (0, "file", "a.txt", 10), (1, "directory", "logs", None), (4, "file", "z.bin", 7)]
    assert [(op.opcode, op.path, op.result, op.detail) for op in log.operations] == [
        ("CalcFileCRC32", "/APM/a.txt", "ACK", "CRC-32 0xdeadbeef"),
        ("RemoveFile", "/APM/../etc/passwd", "NAK FileNotFound", ""),
        ("OpenFileRO", "/nope", "NAK FileNotFound", "")]
    [unsafe] = [f for f in log.findings if f.code == "object-unsafe-path"]
    assert "'/APM/../etc/passwd'" in unsafe.message


def test_listing_names_cannot_add_lines_to_the_listing_file(tmp_path: Path, dialect: Dialect) -> None:
    """Entry names sent with a newline, a tab and an OSC 8 hyperlink (ESC ] ... BEL): the entries keep the
    names as sent, the .listing.txt mavscope writes shows their controls as escapes, one line per entry."""
    flow = Flow()
    first = flow.request(LIST, data=b"/")
    flow.reply(first, data=b"F\x1b]8;;http://x\x07a\t99\0Fx\nmavscope: forged\t5\0")
    flow.nak(flow.request(LIST, data=b"/", offset=2), EOF)
    [obj] = run(flow, tmp_path, dialect).objects
    assert [e["name"] for e in obj.details["entries"]] == ["\x1b]8;;http://x\x07a", "x\nmavscope: forged"]
    assert obj.data == b"file\t\\x1b]8;;http://x\\x07a\t99\nfile\tx\\nmavscope: forged\t5\n"


def test_data_without_its_open_and_reset_sessions(tmp_path: Path, dialect: Dialect) -> None:
    flow = Flow()
    burst = flow.request(BURST, session=3, size=100)  # the capture started after the open
    flow.reply(burst, data=DATA[:100], session=3, burst_complete=1)
    open_req = flow.request(OPEN_RO, data=b"/b")
    flow.reply(open_req, session=4, data=(100).to_bytes(4, "little"))
    req = flow.request(READ, session=4, size=100)
    flow.reply(req, data=DATA[:100], session=4)
    reset = flow.request(RESET)
    flow.reply(reset)
    log = run(flow, tmp_path, dialect)
    orphan, read = log.objects
    assert orphan.path is None and orphan.details["session"] == 3 and orphan.data == DATA[:100]
    assert any("open is not in the capture" in p for p in orphan.problems)
    assert read.path == "/b" and read.complete and read.details["ended_by"] == "ResetSessions"


def test_the_other_direction_and_components(tmp_path: Path, dialect: Dialect) -> None:
    """A companion computer (1/191) reads from the autopilot: sender and receiver follow the frames."""
    flow = Flow(gcs=(1, 191))
    read_file(flow, "/x", DATA[:50])
    [obj] = run(flow, tmp_path, dialect).objects
    assert (obj.sender, obj.receiver, obj.complete) == ((1, 1), (1, 191), True)


def test_acks_are_matched_by_sequence_number(tmp_path: Path, dialect: Dialect) -> None:
    """Two opens in flight: each ACK goes to the request whose sequence number + 1 it carries."""
    flow = Flow()
    a = flow.request(OPEN_RO, data=b"/first")
    b = flow.request(OPEN_RO, data=b"/second")
    flow.reply(b, session=7, data=(4).to_bytes(4, "little"))
    flow.reply(a, session=6, data=(4).to_bytes(4, "little"))
    for session, body in ((6, b"AAAA"), (7, b"BBBB")):
        r = flow.request(READ, session=session, size=4)
        flow.reply(r, data=body)
    objs = {o.path: o.data for o in run(flow, tmp_path, dialect).objects}
    assert objs == {"/first": b"AAAA", "/second": b"BBBB"}
    assert ACK == 128  # the opcode the flows send
