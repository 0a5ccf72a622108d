"""The reconstruction's bookkeeping at a cost per frame that does not grow with what is open.

A hostile capture can keep OPEN_MAX transfers and ORPHANS_ACTIVE stray-frame events open at once (250 x 250
systems exchanging MISSION_COUNTs); scanning them at every frame, to find a frame's transfer and to close
what fell silent, took 200,000 such frames 88 s. Here:

- `PartyIndex` indexes the open transfers (and the events awaiting an answer) by mission type, sender and
  receiver, system or component 0 matching any (`model.same`), so a frame finds its transfers in a few
  lookups;
- `Deadlines` hands back what has been silent for longer than a timeout, oldest silence first, from a heap
  of (last time, object) entries pushed whenever an object's time changes; entries of objects gone or
  touched since are dropped as they surface, and the heap is rebuilt from the live objects when stale
  entries outnumber them (a capture whose clock runs backwards never lets old entries surface).

Both give exactly what a scan of every open object would: the tests hold them to it.
"""

from __future__ import annotations

import heapq
import math
from bisect import bisect_left, insort
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from functools import partial
from itertools import product, repeat
from operator import attrgetter, itemgetter
from typing import Any, Generic, Protocol, TypeVar

from mavscope.analysis.mission.model import Event, Transfer
from mavscope.mavlink.frame import Addr
from mavscope.notes import GivenUp

ANY = -1  # the index's system or component key that any system or component matches


def _keys_of(v: int) -> tuple[int, ...]:
    return (ANY,) if v == 0 else (v, 0)


class Party(Protocol):
    """A transfer or an event: a mission type, two ends, and the order it began in."""

    mission_type: int
    sender: Addr
    order: int


_order = attrgetter("order")  # a Party's order (in C: the index's sorts and bisections run no Python line)


def _receiver(t: Transfer) -> Addr:
    return t.receiver


def _target(ev: Event) -> Addr:
    return ev.target


P = TypeVar("P", bound=Party)


class PartyIndex(Generic[P]):
    """Transfers (the receiver their other end) or events (the target), oldest first, found by mission
    type and both ends, component 0 matching any component (`model.same`)."""

    def __init__(self, other_end: Callable[[P], Addr]) -> None:
        self._other = other_end
        self._all: dict[int, P] = {}  # by order: the order they began in
        self._by: dict[tuple[int, int, int, int, int], list[P]] = {}  # each sorted by order

    def __len__(self) -> int:
        return len(self._all)

    def __iter__(self) -> Iterator[P]:
        return iter(list(self._all.values()))

    def __contains__(self, x: P) -> bool:
        return self._all.get(x.order) is x

    def oldest(self) -> P:
        return next(iter(self._all.values()))

    def newest_but(self, x: P) -> P:
        """The one that began last other than `x` (there are two or more)."""
        it = reversed(self._all.values())
        y = next(it)
        return next(it) if y is x else y

    def _keys(self, x: P) -> Iterator[tuple[int, int, int, int, int]]:
        """Each end filed under its own system and component and under ANY for each (16 keys)."""
        (ssys, scomp), (rsys, rcomp) = x.sender, self._other(x)
        return product((x.mission_type,), (ssys, ANY), (rsys, ANY), (scomp, ANY), (rcomp, ANY))

    def add(self, x: P) -> None:
        self._all[x.order] = x
        self._file(x)

    def remove(self, x: P) -> None:
        if self._all.get(x.order) is x:
            del self._all[x.order]
            self._unfile(x)

    def _file(self, x: P) -> None:
        buckets = map(self._by.setdefault, self._keys(x), map(list, repeat((), 16)))
        deque(map(partial(insort, x=x, key=_order), buckets), maxlen=0)  # insort x into each, in C

    def _unfile(self, x: P) -> None:
        for key in self._keys(x):
            bucket = self._by[key]
            del bucket[bisect_left(bucket, x.order, key=_order)]
            if not bucket:
                del self._by[key]

    def _buckets(self, mtype: int, sender: Addr, other: Addr, exact_sender: bool) -> list[list[P]]:
        """The buckets of what `same` matches to both ends (`exact_sender`: the sender equal): disjoint,
        their union exact. Per field: a query of 0 takes the ANY bucket (everything), any other value its
        own bucket and that of the objects whose field is 0 (a broadcast end). (map and filter: the 16
        lookups run in C.)"""
        ss = (sender[0],) if exact_sender else _keys_of(sender[0])
        sks = (sender[1],) if exact_sender else _keys_of(sender[1])
        return list(filter(None, map(self._by.get, product((mtype,), ss, _keys_of(other[0]), sks,
                                                              _keys_of(other[1])))))

    def matching(self, mtype: int, sender: Addr, other: Addr, exact_sender: bool = False) -> list[P]:
        """Those of `mtype` from `sender` to `other`, oldest first."""
        out = [x for b in self._buckets(mtype, sender, other, exact_sender) for x in b]
        out.sort(key=_order)
        return out

    def latest(self, mtype: int, sender: Addr, other: Addr, exact_sender: bool = False) -> P | None:
        """The one of `mtype` from `sender` to `other` that began last."""
        return max(map(itemgetter(-1), self._buckets(mtype, sender, other, exact_sender)), key=_order, default=None)

    def first(self, mtype: int, sender: Addr, other: Addr, exact_sender: bool = False) -> P | None:
        """The one of `mtype` from `sender` to `other` that began first."""
        return min(map(itemgetter(0), self._buckets(mtype, sender, other, exact_sender)), key=_order, default=None)

    def between(self, mtype: int, a: Addr, b: Addr) -> list[P]:
        """Those of `mtype` between `a` and `b`, either way, oldest first."""
        both = {x.order: x for x in (*self.matching(mtype, a, b), *self.matching(mtype, b, a))}
        return [both[k] for k in sorted(both)]


LISTED_MAX = 1 << 14  # transfers listed, and operations (clears, set-currents, requests, stray frames) listed


def listed(items: list[Any], what: str, given_up: GivenUp) -> None:
    """`items`, the transfers or the operations listed, the one just added last: past LISTED_MAX the newest but
    that one leaves the listing (a flood of COUNTs or stray frames churns its own; what came before stays),
    said on `given_up`. (It may still be followed: what it gets is not listed.)"""
    if len(items) > LISTED_MAX:
        old, new = items.pop(-2), items[-1]
        at = f" (frame {old.frames[0]})" if old.frames else ""
        given_up.add(f"{what} of {party(old.sender)}{at} not listed", record=new.frames[-1] if new.frames else None)


def party(a: Addr) -> str:
    return f"{a[0]}/{a[1]}"


def newest_young(young: dict[int, Transfer], index: PartyIndex[Transfer]) -> Transfer | None:
    """Take out of `young` (open transfers by order, some since answered or closed) the newest still open and
    unanswered; those answered or closed on the way leave it (each once: amortised O(1))."""
    while young:
        k = next(reversed(young))
        t = young.pop(k)
        if not t.answered and t in index:
            return t
    return None


def open_transfers() -> PartyIndex[Transfer]:
    return PartyIndex(_receiver)


def open_events() -> PartyIndex[Event]:
    return PartyIndex(_target)


def _refile(index: PartyIndex[Any], item: Any, attr: str, value: Addr) -> None:
    """Set `item`'s party `attr` to `value`; an item open in `index` is filed again under it."""
    filed = item in index
    if filed:
        index._unfile(item)
    setattr(item, attr, value)
    if filed:
        index._file(item)


def narrow(index: PartyIndex[Transfer], t: Transfer, receiver: Addr) -> None:
    """Set the receiver of `t` (open or not) to `receiver` (the party that answered); an open transfer
    keeps its place among the open ones."""
    _refile(index, t, "receiver", receiver)


def retarget(index: PartyIndex[Event], ev: Event, target: Addr) -> None:
    """Set the target of an event (open or not) to the party that answered it."""
    _refile(index, ev, "target", target)


class Timed(Protocol):
    last: float | None


class Deadlines:
    """Objects with a time of last activity (`last`), handed back once silent for longer than `timeout`."""

    def __init__(self, timeout: float) -> None:
        self.timeout = timeout
        self._heap: list[tuple[float, int, Timed]] = []
        self._pushed = 0

    def push(self, obj: Timed) -> None:
        """Call whenever `obj.last` changes (and when it is first followed). A time that is not finite never
        goes stale (as `now - last > timeout` says), so it is not pushed."""
        if obj.last is not None and math.isfinite(obj.last):
            self._pushed += 1
            heapq.heappush(self._heap, (obj.last, self._pushed, obj))

    def due(self, now: float, live: Callable[[Timed], bool]) -> list[Timed]:
        """The live objects whose `now - last > timeout`, by their last time; each is handed back once (the
        caller ends following them, or pushes them again)."""
        heap, out, seen = self._heap, [], set()
        while heap and now - heap[0][0] > self.timeout:
            last, _, obj = heapq.heappop(heap)
            if obj.last == last and id(obj) not in seen and live(obj):
                seen.add(id(obj))
                out.append(obj)
        return out

    def compact(self, count: int, live: Callable[[], Iterable[Timed]]) -> None:
        """With `count` objects followed, rebuild the heap from them (`live()`) when stale entries are most
        of it: amortised, a constant cost per push."""
        if len(self._heap) > 4 * count + 4096:
            self._heap = []
            for obj in live():
                self.push(obj)
