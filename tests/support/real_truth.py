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
- Mission transfers (mission protocol) and images (image transmission protocol): their functions say
  how.
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
    {"open_nak": error name} or {"session", "announced_size", "length", "sha256", "gaps", "data_acks", "eof_nak":
    {"index"} | None} (gaps: [start, end) ranges before `length` that no data covered; data_acks: the ACKs
    of reads in the session before its EOF)."""
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
                         eof_nak=None, data_acks=0)
                by_session[session] = r
                chunks[session] = {}
        elif req in (FTP_READ, FTP_BURST) and session in by_session and by_session[session]["eof_nak"] is None:
            if opcode == FTP_ACK:
                chunks[session].setdefault(offset, data)
                by_session[session]["data_acks"] += 1
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


MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID = 6, 8


def _is_vehicle(msgs: list[Msg], upto: int, src: tuple[int, int]) -> bool:
    """Whether `src`'s last HEARTBEAT before message `upto` names a vehicle (not a ground station, an
    autopilot other than MAV_AUTOPILOT_INVALID)."""
    for m in reversed(msgs[:upto]):
        if m.name == "HEARTBEAT" and m.src == src:
            return m.msg.type != MAV_TYPE_GCS and m.msg.autopilot != MAV_AUTOPILOT_INVALID
    return False


def mission_transfers(msgs: list[Msg]) -> list[dict[str, Any]]:
    """Every mission transfer by the mission protocol's rules, in order of its MISSION_COUNT:
    {"mission_type", "direction", "from", "to", "count", "count_times", "received": set of item seqs,
    "missing": [seqs], "final_ack": None | {"from": "receiver" | "sender", "result"}}.

    A transfer opens at a MISSION_COUNT from its sender (the side that has the items) to its target
    (the receiver). It is a download when the receiver asked with MISSION_REQUEST_LIST of that mission
    type, or when the sender is a vehicle by its HEARTBEAT; else an upload. The same COUNT again while it
    is open is a retry of it (no time limit: this derivation keeps no clock). The items are the
    MISSION_ITEM(_INT)s of that type from the sender to the receiver while it is open. A MISSION_ACK of
    that type from the receiver to the sender closes it (MAV_MISSION_ACCEPTED: done); one from the sender
    to the receiver cancels it."""
    out: list[dict[str, Any]] = []
    open_: dict[tuple[tuple[int, int], tuple[int, int], int], dict[str, Any]] = {}
    asked: set[tuple[tuple[int, int], tuple[int, int], int]] = set()  # (requester, supplier, type)
    for i, m in enumerate(msgs):
        if m.name not in ("MISSION_REQUEST_LIST", "MISSION_COUNT", "MISSION_ITEM", "MISSION_ITEM_INT", "MISSION_ACK"):
            continue
        mtype = getattr(m.msg, "mission_type", 0) or 0
        target = (m.msg.target_system, m.msg.target_component)
        if m.name == "MISSION_REQUEST_LIST":
            asked.add((m.src, target, mtype))
        elif m.name == "MISSION_COUNT":
            key = (m.src, target, mtype)
            t = open_.get(key)
            if t is not None and t["count"] == m.msg.count:
                t["count_times"].append(m.time)
                continue
            download = (target, m.src, mtype) in asked or _is_vehicle(msgs, i, m.src)
            asked.discard((target, m.src, mtype))
            t = {"mission_type": mtype, "direction": "download" if download else "upload", "from": m.src,
                 "to": target, "count": m.msg.count, "count_times": [m.time], "received": set(), "missing": [],
                 "final_ack": None}
            out.append(t)
            open_[key] = t
        elif m.name in ("MISSION_ITEM", "MISSION_ITEM_INT"):
            t = open_.get((m.src, target, mtype))
            if t is not None and m.msg.seq < t["count"]:
                t["received"].add(m.msg.seq)
        else:  # MISSION_ACK
            t = open_.pop((target, m.src, mtype), None)  # the receiver's answer to the sender
            side = "receiver"
            if t is None:
                t = open_.pop((m.src, target, mtype), None)  # the sender giving up
                side = "sender"
            if t is not None:
                t["final_ack"] = {"from": side, "result": m.msg.type}
    for t in out:
        t["missing"] = sorted(set(range(t["count"])) - t["received"])
    return out


def images(msgs: list[Msg]) -> dict[str, Any]:
    """Images sent with the image transmission protocol: a DATA_TRANSMISSION_HANDSHAKE announces an image of
    `size` bytes in `packets` ENCAPSULATED_DATA packets of `payload` bytes (seqnr 0..packets-1); the packets
    that follow it, until the next handshake of its sender, are that image's. {"images": [{"sender",
    "size", "packets", "payload", "width", "missing": [seqnr], "duplicates", "sha256" (the packets' data
    in seqnr order, zeros where one is missing, cut to `size`)}], "orphans": packets before any handshake}."""
    out: list[dict[str, Any]] = []
    current: dict[tuple[int, int], tuple[dict[str, Any], dict[int, bytes]]] = {}
    orphans = 0

    def close(img: dict[str, Any], got: dict[int, bytes]) -> None:
        n, size = img["packets"], img["payload"]
        data = b"".join(got.get(i, b"\0" * size)[:size].ljust(size, b"\0") for i in range(n))[: img["size"]]
        img.update(missing=[i for i in range(n) if i not in got], sha256=hashlib.sha256(data).hexdigest())

    for m in msgs:
        if m.name == "DATA_TRANSMISSION_HANDSHAKE":
            if m.src in current:
                close(*current[m.src])
            img = {"sender": m.src, "size": m.msg.size, "packets": m.msg.packets, "payload": m.msg.payload,
                   "width": m.msg.width, "duplicates": 0}
            out.append(img)
            current[m.src] = (img, {})
        elif m.name == "ENCAPSULATED_DATA":
            if m.src not in current:
                orphans += 1
                continue
            img, got = current[m.src]
            if m.msg.seqnr in got:
                img["duplicates"] += 1
            else:
                got[m.msg.seqnr] = bytes(m.msg.data)
    for img, got in current.values():
        close(img, got)
    return {"images": out, "orphans": orphans}
