"""Logs downloaded with the log protocol (https://mavlink.io/en/services/log.html): LOG_REQUEST_LIST,
LOG_ENTRY (id and size of each log), LOG_REQUEST_DATA (id, offset, count), LOG_DATA (id, offset, count,
90 bytes), LOG_REQUEST_END.

A download of log `id` from a vehicle starts with the first LOG_REQUEST_DATA for it; a client that lost
packets asks again for the missing ranges (MAVProxy and Mission Planner do), which the same download
takes in. LOG_DATA is placed by its offset; one with fewer than 90 bytes ends the log (ArduPilot sends a
short or empty one at the end); else the size from LOG_ENTRY is the end. LOG_REQUEST_END, or a request
for a log already complete, ends the download. LOG_DATA has no target field: it goes to whoever asked.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable

from mavscope.analysis.objects.context import Context
from mavscope.analysis.objects.model import DOWNLOAD, Addr, Transfer, int_field
from mavscope.analysis.objects.model import LOG as KIND
from mavscope.fields.containers.others import LOG
from mavscope.mavlink.frame import Frame

LOG_DATA_LEN = 90
SIZES_KEPT = 4096  # LOG_ENTRY sizes remembered (per vehicle system and log id)



class LogTracker:
    def __init__(self, ctx: Context) -> None:
        self.ctx = ctx
        self.sizes: OrderedDict[tuple[int, int], int] = OrderedDict()  # (vehicle sysid, log id) -> size
        self.downloads: dict[tuple[int, int], Transfer] = {}  # (vehicle sysid, log id) -> download

    def feed(self, f: Frame, name: str, fields: dict[str, object]) -> None:
        if name == "LOG_ENTRY":
            key = (f.sysid, int_field(fields, "id"))
            self.sizes[key] = int_field(fields, "size")
            self.sizes.move_to_end(key)
            if len(self.sizes) > SIZES_KEPT:
                self.sizes.popitem(last=False)
        elif name == "LOG_REQUEST_DATA":
            self._request(f, fields)
        elif name == "LOG_DATA":
            self._data(f, fields)
        elif name == "LOG_REQUEST_END":
            vehicle = int_field(fields, "target_system")
            for key in [k for k in self.downloads if k[0] == vehicle]:
                t = self.downloads[key]
                if t.receiver is None or t.receiver == (f.sysid, f.compid):
                    t.see(f, self.ctx.tick)
                    t.details["ended_by"] = "LOG_REQUEST_END"
                    self._finish(key)

    def _start(self, key: tuple[int, int], sender: Addr, receiver: Addr | None) -> Transfer:
        t = self.ctx.start(KIND, DOWNLOAD, sender, receiver, self._closer(key))
        t.name = f"log {key[1]}"
        t.details["log_id"] = key[1]
        t.announced = self.sizes.get(key)
        self.downloads[key] = t
        return t

    def _request(self, f: Frame, fields: dict[str, object]) -> None:
        key = (int_field(fields, "target_system"), int_field(fields, "id"))
        t = self.downloads.get(key)
        if t is not None and self._complete(t):
            self._finish(key)
            t = None
        if t is None:
            t = self._start(key, (key[0], int_field(fields, "target_component")), (f.sysid, f.compid))
        t.see(f, self.ctx.tick)
        t.details["requests"] = t.details.get("requests", 0) + 1
        if t.announced is None:
            t.announced = self.sizes.get(key)

    def _data(self, f: Frame, fields: dict[str, object]) -> None:
        key = (f.sysid, int_field(fields, "id"))
        t = self.downloads.get(key)
        if t is None:
            t = self._start(key, (f.sysid, f.compid), None)
            t.problem("its LOG_REQUEST_DATA is not in the capture")
        t.sender = (f.sysid, f.compid)
        t.see(f, self.ctx.tick)
        ofs, count = int_field(fields, "ofs"), int_field(fields, "count")
        valid = LOG(f)
        data = valid.data if valid is not None else b""
        if valid is not None and valid.problem is not None:
            t.problem(valid.problem)
        t.content.add(ofs, data)
        t.details["packets"] = t.details.get("packets", 0) + 1
        if count < LOG_DATA_LEN:  # the end of the log
            t.end_at = ofs + count if t.end_at is None else min(t.end_at, ofs + count)

    def _complete(self, t: Transfer) -> bool:
        size = self._size(t)
        return size is not None and not t.content.gaps(size)

    def _size(self, t: Transfer) -> int | None:
        if t.end_at is not None:
            return t.end_at
        return t.announced

    def _closer(self, key: tuple[int, int]) -> Callable[[Transfer], None]:
        def close(t: Transfer) -> None:
            if self.downloads.get(key) is t:
                self._finish(key)
        return close

    def _finish(self, key: tuple[int, int]) -> None:
        t = self.downloads.pop(key, None)
        if t is None:
            return
        c = t.content
        size = self._size(t)
        end_known = size is not None
        if size is None or size < c.end:
            if size is not None:
                t.problem(f"data up to offset {c.end}, past the end the vehicle gave ({size})")
            size, end_known = c.end, False
        if t.end_at is not None and t.announced is not None and t.end_at != t.announced:
            t.problem(f"LOG_ENTRY said {t.announced} bytes, the last LOG_DATA ended at {t.end_at}")
        gaps = c.gaps(size)
        self.ctx.finish(t, size=size, gaps=gaps, end_known=end_known, complete=end_known and not gaps,
                        received=c.received, extension=".bin")

    def close_all(self) -> None:
        for key in list(self.downloads):
            self._finish(key)
