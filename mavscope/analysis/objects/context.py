"""What the object trackers share: the limits and the memory budget, the transfers in progress (at most
`Limits.max_open`: the least recently active one is closed early when another starts), the finished
records, the FTP operations, and what the limits made the reconstruction give up."""

from __future__ import annotations

import heapq
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, replace

from mavscope.analysis.objects.content import Budget
from mavscope.analysis.objects.model import (
    Addr,
    FtpOperation,
    Limits,
    ObjectRecord,
    Transfer,
    new_transfer,
    record_of,
)
from mavscope.analysis.objects.names import file_name


@dataclass
class Op:
    """An FTP operation while its answer is awaited (frozen into an FtpOperation at the end)."""

    time: float | None
    frame: int
    client: Addr
    server: Addr | None
    opcode: str
    path: str | None
    new_path: str | None
    result: str | None = None
    reply_frame: int | None = None
    detail: str = ""
    retries: int = 0
    became_object: bool = False  # an open the server accepted: the object is reported, not the operation

    def freeze(self) -> FtpOperation:
        detail = self.detail + (f"; sent {self.retries + 1} times" if self.retries else "")
        return FtpOperation(self.time, self.frame, self.client, self.server, self.opcode, self.path,
                            self.new_path, self.result, self.reply_frame, detail.lstrip("; "))


class Context:
    def __init__(self, limits: Limits) -> None:
        self.limits = limits
        self.budget = Budget(limits.max_total, limits.max_holes)
        self.tick = 0  # frames seen (the activity clock of the open transfers)
        self.order = 0  # transfers started
        self.open: dict[int, tuple[Transfer, Callable[[], None]]] = {}  # id -> (transfer, how to close it)
        # (last_seen, order, id) of the open transfers as they were when pushed: stale entries (a transfer
        # seen since, or finished) are skipped or pushed again when they surface (`_least_active`)
        self._idle: list[tuple[int, int, int]] = []
        self.records: list[ObjectRecord] = []  # every finished object (bytes dropped once taken)
        self.fresh: list[int] = []  # positions in `records` of those finished since the last take()
        self.ops: list[Op] = []
        self.given_up: Counter[str] = Counter()  # what a limit made the reconstruction give up, and how often
        self.not_kept = 0  # objects finished beyond Limits.max_objects

    def start(self, kind: str, direction: str, sender: Addr | None, receiver: Addr | None,
              close: Callable[[Transfer], None]) -> Transfer:
        """A new transfer, registered as open; `close(t)` is how its tracker finishes it early."""
        t = new_transfer(kind, direction, sender, receiver, self.budget, self.limits)
        self.order += 1
        t.order = self.order
        t.last_seen = self.tick
        if len(self.open) >= self.limits.max_open:
            oldest, closer = self._least_active()
            oldest.problem(f"closed early: more than {self.limits.max_open} transfers were in progress at once")
            self.given_up["transfers closed early (too many in progress at once)"] += 1
            closer()
        self.open[id(t)] = (t, lambda: close(t))
        heapq.heappush(self._idle, (t.last_seen, t.order, id(t)))
        if len(self._idle) > 4 * len(self.open) + 4096:  # mostly finished transfers: rebuild
            self._idle = [(v.last_seen, v.order, k) for k, (v, _) in self.open.items()]
            heapq.heapify(self._idle)
        return t

    def _least_active(self) -> tuple[Transfer, Callable[[], None]]:
        """The open transfer seen least recently (the one started first among equals), as `min` over
        `open` would find it; each stale entry costs one pop, and a push only if the transfer is still open."""
        while True:
            seen, order, key = heapq.heappop(self._idle)
            entry = self.open.get(key)
            if entry is None or entry[0].order != order:  # finished (its id may be another transfer's now)
                continue
            if entry[0].last_seen != seen:
                heapq.heappush(self._idle, (entry[0].last_seen, order, key))
                continue
            return entry

    def finish(self, t: Transfer, *, size: int, gaps: list[tuple[int, int]], end_known: bool, complete: bool,
               received: int, extension: str = "", label: str | None = None, gap_unit: str = "bytes",
               data: bytes | None = None) -> None:
        """Freeze a transfer into its record (its tracker has worked out size, gaps and completeness)."""
        self.open.pop(id(t), None)
        content = t.content
        limit = self.limits.max_object
        if size > limit:
            t.problem(f"its end ({size:,} bytes) is past the {limit:,}-byte object limit: cut there")
            self.given_up[f"objects cut at the {limit:,}-byte object limit"] += 1
            size, complete = limit, False
            if data is not None:
                data = data[:size]
        if data is None:
            held = len(content.buf)
            extra = size - held  # zeros after the last byte received: a hole too
            why = None
            if extra > 0 and not self.budget.take(extra):
                why = "the memory limit for objects"
            elif extra > 0 and not self.budget.hole(extra):
                self.budget.give(extra)
                why = f"the limit of {self.budget.holes:,} bytes of holes"
            if why is not None:
                t.problem(f"{why} was reached: only its first {held:,} bytes were kept")
                self.given_up[f"objects cut short: {why} was reached"] += 1
                size, complete = held, False
            data = content.data(size)
            content.release()
            self.budget.held += min(size, held)  # the record's bytes stay charged until they are taken
        else:
            content.release()
            self.budget.held += len(data)
        if gap_unit == "bytes":
            gaps = [(a, min(b, size)) for a, b in gaps if a < size]
        if content.dropped:
            for p in sorted(content.problems):
                self.given_up[f"{t.name or t.path or t.kind}: {p}"] += 1
        if len(self.records) >= self.limits.max_objects:
            self.not_kept += 1
            self.given_up[f"objects beyond the first {self.limits.max_objects:,} were counted, not kept"] += 1
            self.budget.give(len(data))
            return
        rec = record_of(t, t.order, file_name(t.order, label or t.name or t.path or t.kind, extension), size, gaps,
                        end_known, complete, data, received, gap_unit)
        self.fresh.append(len(self.records))
        self.records.append(rec)

    def take(self) -> list[ObjectRecord]:
        """The records finished since the last call, with their bytes; the context keeps them without."""
        out = []
        for i in self.fresh:
            rec = self.records[i]
            out.append(rec)
            self.records[i] = replace(rec, data=b"")
            self.budget.give(len(rec.data))
        self.fresh = []
        return out

    def close_all(self) -> None:
        for _t, closer in list(self.open.values()):
            closer()

    def operation(self, op: Op) -> Op:
        if len(self.ops) < self.limits.max_operations:
            self.ops.append(op)
        else:
            self.given_up[f"FTP operations beyond the first {self.limits.max_operations:,} were not listed"] += 1
        return op
