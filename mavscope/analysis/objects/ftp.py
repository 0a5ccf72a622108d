"""Files moved over MAVLink FTP (FILE_TRANSFER_PROTOCOL), both directions, rebuilt per session.

The client (a GCS) sends requests to the server (the vehicle, FILE_TRANSFER_PROTOCOL.target_system); the
server answers each with an ACK or NAK whose `req_opcode` names the request and whose sequence number is
the request's + 1 (https://mavlink.io/en/services/ftp.html; ArduPilot's GCS_FTP, PX4's MavlinkFTP,
pymavlink's mavftp). So:

- a read starts with the ACK of an OpenFileRO (its `session`, and the file size the server announces);
  the data comes in ACKs of ReadFile and BurstReadFile, placed by their `offset`; a NAK EOF says where
  the file ends (the offset of the server's read position: ArduPilot announces more than a param.pck
  holds); a retried request or burst brings bytes again (duplicates), a lost packet leaves a gap;
- a write starts with the ACK of a CreateFile or OpenFileWO; the data is in the WriteFile requests and
  each ACK confirms one (a write never acknowledged, or refused, is reported);
- TerminateSession (or ResetSessions, for every session of the server) ends a session, at its ACK;
- a listing is the entries of the ACKs of ListDirectory, placed by entry index (the request's offset),
  ended by a NAK EOF;
- the other requests (remove, rename, create or remove a directory, truncate, CRC-32, and opens the
  server refused) are operations, listed with the server's answer.

Sessions are keyed by (client, server system, session id). Data for a session whose open is not in the
capture makes an object without a path. State is bounded: pending requests per client and server
(`PENDING`), pairs (`PAIRS`), and the context's limits on open transfers and bytes.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass

from mavscope.analysis.objects.content import Ranges
from mavscope.analysis.objects.context import Context, Op
from mavscope.analysis.objects.model import DOWNLOAD, FTP_LIST, FTP_READ, FTP_WRITE, UPLOAD, Addr, Transfer
from mavscope.fields.containers.ftp import (
    ACK,
    BURST,
    CREATE,
    LIST,
    NAK,
    OPEN_RO,
    OPEN_WO,
    READ,
    RESET,
    TERMINATE,
    WRITE,
    Ftp,
    ftp,
    opcode_name,
)
from mavscope.fields.containers.ftp import ERRORS as _ERRORS
from mavscope.mavlink.frame import Frame, plaintext_payload
from mavscope.visible import visible

EOF = 6
PENDING = 64  # requests awaiting an answer, per (client, server)
PAIRS = 256  # (client, server) pairs with pending requests (each request keeps its frame until answered)
REQUESTED_OFFSETS = 256  # read offsets remembered per session (to count retried requests)
ERROR_NAMES = dict(reversed(_ERRORS))
OPENS = (OPEN_RO, CREATE, OPEN_WO)
Pair = tuple[Addr, int]  # (client, server system id)
SessionKey = tuple[Addr, int, int]  # (client, server system id, session)


def error_text(p: Ftp) -> str:
    if p.error is None:
        return "NAK"
    text = f"NAK {ERROR_NAMES.get(p.error, f'error {p.error}')}"
    return text + (f" (errno {p.errno})" if p.errno is not None else "")


def targets(f: Frame) -> tuple[int, int]:
    """FILE_TRANSFER_PROTOCOL.target_system and target_component."""
    payload = plaintext_payload(f)
    md = f.msgdef
    if payload is None or md is None:
        return 0, 0
    sys_f, comp_f = md.field("target_system"), md.field("target_component")
    ts = payload[sys_f.offset] if sys_f is not None and sys_f.offset < len(payload) else 0
    tc = payload[comp_f.offset] if comp_f is not None and comp_f.offset < len(payload) else 0
    return ts, tc


@dataclass
class Request:
    frame: Frame
    opcode: int
    session: int
    offset: int
    length: int  # WriteFile: bytes carried; ReadFile/BurstReadFile: bytes asked
    path: str | None
    op: Op | None = None


class FtpTracker:
    def __init__(self, ctx: Context, paths: Callable[[str], bool] | None = None) -> None:
        """`paths`: follow only reads and writes of the paths it accepts (no listings, no operations, no
        data of sessions whose open is not in the capture); None: everything."""
        self.ctx = ctx
        self.paths = paths
        self.pending: OrderedDict[Pair, OrderedDict[int, Request]] = OrderedDict()
        self.sessions: dict[SessionKey, Transfer | None] = {}  # None: a session of a path not followed
        self.listings: dict[tuple[Addr, int, str], Transfer] = {}

    # -- frames --------------------------------------------------------------------------------------

    def feed(self, f: Frame) -> None:
        p = ftp(f)
        if p is None:
            return
        tsys, tcomp = targets(f)
        if p.opcode in (ACK, NAK):
            self._reply(f, p, (tsys, tcomp))
        else:
            self._request(f, p, tsys)

    def _request(self, f: Frame, p: Ftp, server: int) -> None:
        client = (f.sysid, f.compid)
        pair = (client, server)
        op = p.opcode
        length = len(p.data) if op == WRITE else p.size
        req = Request(f, op, p.session, p.offset, length, p.path)
        tick = self.ctx.tick
        if op in (READ, BURST, WRITE, TERMINATE):
            t = self._session(pair, p.session, create=op == WRITE, frame=f)
            if t is not None:
                t.see(f, tick)
                if op == WRITE:
                    t.details["writes"] = t.details.get("writes", 0) + 1
                    if t.content.covered(p.offset, p.offset + len(p.data)) and p.data:
                        t.details["rewrites"] = t.details.get("rewrites", 0) + 1
                    t.content.add(p.offset, p.data)
                elif op in (READ, BURST):
                    self._count_request(t, p.offset)
                else:
                    t.closed = True
        elif op == RESET:
            for key, t in self.sessions.items():
                if key[1] == server and t is not None:
                    if key[0] == client:
                        t.see(f, tick)
                    t.closed = True
        elif op == LIST and self.paths is None:
            self._listing_request(f, client, server, p)
        elif op in OPENS:
            if self.paths is not None and not (p.path is not None and self.paths(p.path)):
                req.path = None  # not followed: its session is ignored
                req.op = None
            else:
                req.op = self._op(f, client, server, p)
        elif self.paths is None:
            req.op = self._op(f, client, server, p)
        self._remember(pair, p.seq, req)

    def _op(self, f: Frame, client: Addr, server: int, p: Ftp) -> Op:
        queue = self.pending.get((client, server))
        waiting = queue.get((p.seq + 1) & 0xFFFF) if queue is not None else None
        if waiting is not None and waiting.op is not None and waiting.opcode == p.opcode and waiting.path == p.path:
            waiting.op.retries += 1  # the same request again (its answer was lost, or is slow)
            return waiting.op
        return self.ctx.operation(Op(f.time, f.record, client, (server, 0), opcode_name(p.opcode), p.path,
                                     p.new_path))

    def _remember(self, pair: Pair, seq: int, req: Request) -> None:
        waiting = self.pending.get(pair)
        if waiting is None:
            if len(self.pending) >= PAIRS:
                self.pending.popitem(last=False)
            waiting = self.pending[pair] = OrderedDict()
        else:
            self.pending.move_to_end(pair)
        key = (seq + 1) & 0xFFFF
        waiting.pop(key, None)
        waiting[key] = req
        if len(waiting) > PENDING:
            waiting.popitem(last=False)

    def _match(self, pair: Pair, p: Ftp) -> Request | None:
        """The request a reply answers: by sequence number, else the latest one with its opcode."""
        waiting = self.pending.get(pair)
        if not waiting:
            return None
        req = waiting.get(p.seq)
        if req is None or req.opcode != p.req_opcode:
            req = next((r for r in reversed(waiting.values()) if r.opcode == p.req_opcode), None)
        if req is not None and not (p.req_opcode == BURST and p.opcode == ACK and not p.burst_complete):
            key = next((k for k, r in waiting.items() if r is req), None)
            if key is not None:
                del waiting[key]
        return req

    def _reply(self, f: Frame, p: Ftp, client: Addr) -> None:
        server = (f.sysid, f.compid)
        pair = (client, f.sysid)
        req = self._match(pair, p)
        ro = p.req_opcode
        tick = self.ctx.tick
        if req is not None and req.op is not None and ro not in OPENS:
            req.op.result = "ACK" if p.opcode == ACK else error_text(p)
            req.op.reply_frame = f.record
            req.op.server = server
            if p.crc32 is not None:
                req.op.detail = f"CRC-32 0x{p.crc32:08x}"
            return
        if ro in OPENS:
            self._open_reply(f, p, client, server, req)
        elif ro in (READ, BURST):
            t = self._session(pair, p.session, create=p.opcode == ACK, frame=f, server=server)
            if t is None:
                return
            t.see(f, tick)
            if p.opcode == ACK:
                t.content.add(p.offset, p.data)
                t.details["data_packets"] = t.details.get("data_packets", 0) + 1
            elif p.error == EOF:
                t.end_at = p.offset
                t.details["eof_offset"] = p.offset
            else:
                t.problem(f"the server answered a {opcode_name(ro)} at offset {p.offset} with {error_text(p)}")
        elif ro == WRITE:
            t = self._session(pair, p.session, create=False, frame=f, server=server)
            if t is None:
                return
            t.see(f, tick)
            if p.opcode != ACK:
                t.details["refused_writes"] = t.details.get("refused_writes", 0) + 1
                t.problem(f"the server refused a WriteFile at offset {p.offset}: {error_text(p)}")
            elif req is not None and t.acked is not None:
                t.acked.add(req.offset, req.offset + req.length)
            else:
                t.problem("a WriteFile ACK whose request is not in the capture")
        elif ro in (TERMINATE, RESET):
            for key, t2 in list(self.sessions.items()):
                if key[1] != f.sysid or t2 is None:
                    continue
                if (ro == TERMINATE and key == (client, f.sysid, p.session)) or (ro == RESET and t2.closed):
                    if key[0] == client:
                        t2.see(f, tick)
                    t2.details["ended_by"] = opcode_name(ro)
                    self._finish_session(key)
        elif ro == LIST and self.paths is None:
            self._listing_reply(f, p, client, server, req)

    def _open_reply(self, f: Frame, p: Ftp, client: Addr, server: Addr, req: Request | None) -> None:
        ro = p.req_opcode
        if req is not None and req.op is None and self.paths is not None:
            if p.opcode == ACK:  # a session of a path not followed: ignore its data
                self._set_session((client, f.sysid, p.session), None)
            return
        if p.opcode != ACK:
            if req is not None and req.op is not None:
                req.op.result, req.op.reply_frame, req.op.server = error_text(p), f.record, server
            return
        if self.paths is not None and req is None:
            self._set_session((client, f.sysid, p.session), None)
            return
        path = req.path if req is not None else None
        read = ro == OPEN_RO
        key = (client, f.sysid, p.session)
        t = self.ctx.start(FTP_READ if read else FTP_WRITE, DOWNLOAD if read else UPLOAD,
                           server if read else client, client if read else server, self._closer(key))
        t.path, t.name = path, path or ""
        t.details["session"] = p.session
        t.details["opened_by"] = opcode_name(ro)
        if req is not None:
            t.see(req.frame, self.ctx.tick)
            if req.op is not None:
                req.op.became_object = True
        else:
            t.problem(f"the {opcode_name(ro)} request is not in the capture: the path is unknown")
        t.see(f, self.ctx.tick)
        if read:
            t.announced = p.file_size
        else:
            t.acked = Ranges(self.ctx.limits.max_ranges)
            if p.file_size is not None:
                t.details["size_before"] = p.file_size
        self._set_session(key, t)

    # -- sessions ------------------------------------------------------------------------------------

    def _session(self, pair: Pair, session: int, *, create: bool, frame: Frame,
                 server: Addr | None = None) -> Transfer | None:
        key = (pair[0], pair[1], session)
        if key in self.sessions:
            return self.sessions[key]
        if self.paths is not None or not create:
            return None
        # data of a session whose open the capture does not hold
        client = pair[0]
        srv = server if server is not None else (pair[1], 0)
        write = frame.sysid == client[0] and frame.compid == client[1]
        t = self.ctx.start(FTP_WRITE if write else FTP_READ, UPLOAD if write else DOWNLOAD,
                           client if write else srv, srv if write else client, self._closer(key))
        t.details["session"] = session
        t.problem("its open is not in the capture: the path is unknown")
        if write:
            t.acked = Ranges(self.ctx.limits.max_ranges)
        self._set_session(key, t)
        return t

    def _set_session(self, key: SessionKey, t: Transfer | None) -> None:
        if key in self.sessions:
            self._finish_session(key)
        self.sessions[key] = t
        if len(self.sessions) > PAIRS * 4:  # forget ignored sessions first, then the oldest
            drop = next((k for k, v in self.sessions.items() if v is None), next(iter(self.sessions)))
            self._finish_session(drop)

    def _closer(self, key: SessionKey) -> Callable[[Transfer], None]:
        def close(t: Transfer) -> None:
            if self.sessions.get(key) is t:
                self._finish_session(key)
            else:
                self._finish(t)
        return close

    def _finish_session(self, key: SessionKey) -> None:
        t = self.sessions.pop(key, None)
        if t is not None:
            self._finish(t)

    def _count_request(self, t: Transfer, offset: int) -> None:
        t.details["requests"] = t.details.get("requests", 0) + 1
        seen: dict[int, None] = t.details.setdefault("_offsets", {})
        if offset in seen:
            t.details["retried_requests"] = t.details.get("retried_requests", 0) + 1
        elif len(seen) < REQUESTED_OFFSETS:
            seen[offset] = None

    def _finish(self, t: Transfer) -> None:
        t.details.pop("_offsets", None)
        c = t.content
        if t.kind == FTP_WRITE:
            size = c.end
            gaps = c.gaps(size)
            unacked = t.acked.missing(size) if t.acked is not None else [(0, size)]
            if unacked:
                t.details["unacknowledged"] = [list(r) for r in unacked[:64]]
            end_known = t.closed
            complete = bool(size) and not gaps and not unacked
            self.ctx.finish(t, size=size, gaps=gaps, end_known=end_known, complete=complete, received=c.received)
            return
        end_known = False
        if t.end_at is not None:
            size = t.end_at
            end_known = True
            if size < c.end:
                t.problem(f"the server reported the end of file at {size}, but sent data up to {c.end}")
                size, end_known = c.end, False
        elif t.announced is not None and t.announced >= c.end:
            size = t.announced
            end_known = c.end == t.announced
        else:
            size = c.end
        gaps = c.gaps(size)
        self.ctx.finish(t, size=size, gaps=gaps, end_known=end_known, complete=end_known and not gaps,
                        received=c.received)

    # -- listings ------------------------------------------------------------------------------------

    def _listing_request(self, f: Frame, client: Addr, server: int, p: Ftp) -> None:
        if p.path is None:
            return
        key = (client, server, p.path)
        t = self.listings.get(key)
        if t is None or (p.offset == 0 and t.end_at is not None):
            if t is not None:
                self._finish_listing(key)
            t = self.ctx.start(FTP_LIST, DOWNLOAD, (server, 0), client, self._listing_closer(key))
            t.path, t.name = p.path, p.path
            t.details["entries"] = {}
            self.listings[key] = t
            if len(self.listings) > PAIRS:
                self._finish_listing(next(iter(self.listings)))
        t.see(f, self.ctx.tick)

    def _listing_reply(self, f: Frame, p: Ftp, client: Addr, server: Addr, req: Request | None) -> None:
        t = None
        if req is not None and req.path is not None:
            t = self.listings.get((client, f.sysid, req.path))
        if t is None:
            t = next((v for (c, s, _), v in reversed(self.listings.items()) if c == client and s == f.sysid), None)
        if t is None:
            return
        t.sender = server
        t.see(f, self.ctx.tick)
        first = req.offset if req is not None else p.offset
        entries: dict[int, tuple[str, str, int | None]] = t.details["entries"]
        if p.opcode == ACK:
            for i, e in enumerate(p.entries):
                index = first + i
                old = entries.get(index)
                value = (e.kind, e.name, e.size)
                if old is None:
                    if len(entries) < self.ctx.limits.max_entries:
                        entries[index] = value
                    else:
                        t.problem(f"more than {self.ctx.limits.max_entries:,} entries: later ones not kept")
                elif old != value:
                    t.problem(f"entry {index} sent twice with different contents")
        elif p.error == EOF:
            t.end_at = first
            self._finish_listing((client, f.sysid, t.path or ""))
        else:
            t.problem(f"the server answered ListDirectory with {error_text(p)}")
            self._finish_listing((client, f.sysid, t.path or ""))

    def _listing_closer(self, key: tuple[Addr, int, str]) -> Callable[[Transfer], None]:
        def close(t: Transfer) -> None:
            if self.listings.get(key) is t:
                self._finish_listing(key)
        return close

    def _finish_listing(self, key: tuple[Addr, int, str]) -> None:
        t = self.listings.pop(key, None)
        if t is None:
            return
        entries: dict[int, tuple[str, str, int | None]] = t.details.pop("entries")
        end = t.end_at if t.end_at is not None else (max(entries) + 1 if entries else 0)
        missing = []
        pos = 0
        for i in sorted(entries):
            if i >= end:
                break
            if i > pos:
                missing.append((pos, i))
            pos = i + 1
        if pos < end:
            missing.append((pos, end))
        lines = []
        listed = []
        for i in sorted(entries):
            kind, name, size = entries[i]
            listed.append({"index": i, "type": kind, "name": name, "size": size})
            # the text file is mavscope's rendering: a name's controls (a newline, a tab, ESC) as escapes, so
            # that a name cannot add a line or a column, or reach a terminal showing the file (`kind` is one
            # of ENTRY_KINDS' words)
            lines.append(f"{kind}\t{visible(name)}" + (f"\t{size}" if size is not None else "") + "\n")
        data = "".join(lines).encode("utf-8", "backslashreplace")
        t.details["entries"] = listed
        self.ctx.finish(t, size=len(data), gaps=missing, end_known=t.end_at is not None,
                        complete=t.end_at is not None and not missing, received=len(entries), gap_unit="entries",
                        extension=".listing.txt", data=data)

    def close_all(self) -> None:
        for key in list(self.sessions):
            self._finish_session(key)
        for lkey in list(self.listings):
            self._finish_listing(lkey)
