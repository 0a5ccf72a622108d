"""Facts of a real capture derived from pymavlink's messages alone (tests/support/pymavlink_reader.py), by
the protocols' rules as their specifications state them, with no mavscope import: the independent side
of the story and parameter tests on ../shared/real-captures.

- Commands (MAVLink command protocol): a COMMAND_LONG or COMMAND_INT opens a command of (sender, target
  system, command); the same one again before its answer is another attempt of it. A COMMAND_ACK from the
  target system with that command number answers the oldest open one whose sender the ACK's target fields
  name (0 where the sender left them out: broadcast).
- Parameter sets (parameter protocol): a PARAM_SET asks the target system for a value; the first
  PARAM_VALUE of that name from the target system after it answers it, confirmed when the value it
  reports is the one asked for (as float32 bits: the protocol's encoding).
- MAVLink FTP reads (FILE_TRANSFER_PROTOCOL payload: seq u16, session u8, opcode u8, size u8, req_opcode u8,
  burst_complete u8, padding u8, offset u32, data): each OpenFileRO (4) request and the server's answer
  to it, ACK (128, data a u32 file size, the session in the header) or NAK (129, data[0] the error);
  the file is the data of the ACKs of ReadFile (5) and BurstReadFile (15) in that session, at their
  offsets, until the NAK EOF (error 6) of one of them.
- Signing streams: the (sender, link id) of every signed v2 frame (incompat flag 1; the link id is the
  first byte of the 13-byte signature).
"""

from __future__ import annotations

import hashlib
import struct
from typing import Any

from tests.support.pymavlink_reader import Msg

FTP_OPEN_RO, FTP_READ, FTP_BURST, FTP_ACK, FTP_NAK = 4, 5, 15, 128, 129
FTP_EOF = 6
# MAV_FTP_ERR (common.xml's FILE_TRANSFER_PROTOCOL description and the FTP specification)
FTP_ERRORS = {0: "None", 1: "Fail", 2: "FailErrno", 3: "InvalidDataSize", 4: "InvalidSession",
              5: "NoSessionsAvailable", 6: "EOF", 7: "UnknownCommand", 8: "FileExists", 9: "FileProtected",
              10: "FileNotFound"}


def commands(msgs: list[Msg]) -> list[dict[str, Any]]:
    """[{"command", "sender", "target", "attempts": [times], "ack": None | {"result", "time"}}] in order."""
    out: list[dict[str, Any]] = []
    open_: list[dict[str, Any]] = []
    for m in msgs:
        if m.name in ("COMMAND_LONG", "COMMAND_INT"):
            key = (m.src, m.msg.target_system, m.msg.command)
            same = [c for c in open_ if (c["sender"], c["target"][0], c["command"]) == key]
            if same:
                same[0]["attempts"].append(m.time)
                continue
            c = {"command": m.msg.command, "sender": m.src, "target": (m.msg.target_system, m.msg.target_component),
                 "attempts": [m.time], "ack": None}
            out.append(c)
            open_.append(c)
        elif m.name == "COMMAND_ACK":
            to = (getattr(m.msg, "target_system", 0), getattr(m.msg, "target_component", 0))
            for c in open_:
                if c["command"] == m.msg.command and c["target"][0] == m.src[0] and \
                        to[0] in (0, c["sender"][0]) and to[1] in (0, c["sender"][1]):
                    c["ack"] = {"result": m.msg.result, "time": m.time}
                    open_.remove(c)
                    break
    return out


def param_sets(msgs: list[Msg]) -> list[dict[str, Any]]:
    """[{"time", "name", "value", "confirmed", "latency_s"}] of every PARAM_SET, in order."""
    out: list[dict[str, Any]] = []
    waiting: list[tuple[int, str, dict[str, Any]]] = []
    for m in msgs:
        if m.name == "PARAM_SET":
            s = {"time": m.time, "name": m.msg.param_id, "value": m.msg.param_value, "confirmed": False,
                 "latency_s": None}
            out.append(s)
            waiting.append((m.msg.target_system, m.msg.param_id, s))
        elif m.name == "PARAM_VALUE":
            for w in waiting:
                target, name, s = w
                if target == m.src[0] and name == m.msg.param_id:
                    s["confirmed"] = struct.pack("<f", m.msg.param_value) == struct.pack("<f", s["value"])
                    s["latency_s"] = m.time - s["time"]
                    waiting.remove(w)
                    break
    return out


def _ftp(m: Msg) -> tuple[int, int, int, int, int, int, bytes]:
    """(seq, session, opcode, size, req_opcode, offset, data) of a FILE_TRANSFER_PROTOCOL frame."""
    p = bytes(m.msg.payload).ljust(251, b"\0")
    seq, session, opcode, size, req, _burst, _pad, offset = struct.unpack_from("<HBBBBBBI", p)
    return seq, session, opcode, size, req, offset, p[12 : 12 + size]


def ftp_reads(msgs: list[Msg]) -> list[dict[str, Any]]:
    """Every OpenFileRO, in order: {"open_index", "open_time", "client", "path"} and then either
    {"open_nak": error name} or {"session", "announced_size", "length", "sha256", "gaps", "eof_nak":
    {"index"} | None} (gaps: [start, end) ranges before `length` that no data covered)."""
    out: list[dict[str, Any]] = []
    asked: dict[tuple[int, int], dict[str, Any]] = {}  # (client sysid, compid) -> the open awaiting its answer
    by_session: dict[int, dict[str, Any]] = {}
    chunks: dict[int, dict[int, bytes]] = {}
    for m in msgs:
        if m.name != "FILE_TRANSFER_PROTOCOL":
            continue
        _seq, session, opcode, size, req, offset, data = _ftp(m)
        client = (m.msg.target_system, m.msg.target_component)
        if opcode == FTP_OPEN_RO:
            r = {"open_index": m.index, "open_time": m.time, "client": m.src,
                 "path": data.split(b"\0")[0].decode("utf-8", "replace")}
            out.append(r)
            asked[m.src] = r
        elif opcode in (FTP_ACK, FTP_NAK) and req == FTP_OPEN_RO and client in asked:
            r = asked.pop(client)
            if opcode == FTP_NAK:
                r["open_nak"] = FTP_ERRORS.get(data[0] if data else -1, str(data[0] if data else None))
            else:
                r.update(session=session, announced_size=struct.unpack_from("<I", data.ljust(4, b"\0"))[0],
                         eof_nak=None)
                by_session[session] = r
                chunks[session] = {}
        elif req in (FTP_READ, FTP_BURST) and session in by_session and by_session[session]["eof_nak"] is None:
            if opcode == FTP_ACK:
                chunks[session].setdefault(offset, data)
            elif opcode == FTP_NAK and data[:1] == bytes([FTP_EOF]):
                by_session[session]["eof_nak"] = {"index": m.index, "offset": offset}
    for session, r in by_session.items():
        got = chunks[session]
        length = max((o + len(d) for o, d in got.items()), default=0)
        content = bytearray(length)
        covered = bytearray(length)
        for o, d in got.items():
            content[o : o + len(d)] = d
            covered[o : o + len(d)] = b"\1" * len(d)
        gaps, start = [], None
        for i, c in enumerate(covered):
            if not c and start is None:
                start = i
            elif c and start is not None:
                gaps.append([start, i])
                start = None
        r.update(length=length, sha256=hashlib.sha256(content).hexdigest(), gaps=gaps)
    return out


def signing_streams(msgs: list[Msg]) -> list[str]:
    """"sysid/compid link N" of each (sender, link id) that signed a frame, in order of their first frame."""
    seen: dict[str, None] = {}
    for m in msgs:
        buf = bytes(m.msg._msgbuf)  # noqa: SLF001 - the frame's bytes, as pymavlink parsed them
        if buf[0] == 0xFD and buf[2] & 1 and len(buf) >= 12 + buf[1] + 13:
            seen.setdefault(f"{m.src[0]}/{m.src[1]} link {buf[-13]}", None)
    return list(seen)
