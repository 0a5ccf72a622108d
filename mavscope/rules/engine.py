"""Running rules over frames: `RuleSet` compiles them once for a dialect, `RuleEngine` evaluates each frame in
capture order and gives the findings at the end (docs/rules.md).

Fast where it matters: each rule's filter is read for the messages it can match (prefilter.py) and the rules
are indexed by message id, so a frame of a message no rule names costs one dictionary look-up; the payload
is decoded once per frame, only when a rule of its message needs it (the caller's decoding reused). Only
frames whose CRC checked out are judged (a receiver drops the others). Bounded: the threshold counters per
rule (MAX_KEYS senders or links each; a flood of made-up senders churns its own newest entries, never the
established ones: notes.pop_newest) and the state of state.py, each bound's give-ups said as a `capacity`
finding.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Hashable, Iterable, Sequence
from dataclasses import dataclass

from mavscope.analysis.vehicles import Systems
from mavscope.fields.registry import FieldRegistry
from mavscope.filter import DisplayFilter, FilterError, compile_filter
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import SIGNING_EPOCH, CrcStatus, Frame, decode_payload
from mavscope.notes import Finding, FrameNumbers, GivenUp, pop_newest
from mavscope.rules.loader import RuleError, load_rules
from mavscope.rules.model import Per, Rule, SenderState
from mavscope.rules.prefilter import filter_scope
from mavscope.rules.state import (
    EXTENDED_SYS_STATE,
    GLOBAL_POSITION_INT,
    HEARTBEAT,
    Fields,
    FirstSenders,
    SigningLinks,
    VehicleState,
    link_of,
)

MAX_KEYS = 4096  # senders or links a rule's threshold counts at once
FRAMES_KEPT = 64  # frame numbers a rule's finding lists (every match counted)
TARGET_FIELDS = ("target_system", "target")  # MANUAL_CONTROL's is `target`


@dataclass(frozen=True, slots=True)
class Compiled:
    rule: Rule
    filter: DisplayFilter
    messages: frozenset[int] | None  # the message ids its filter can match (None: any)
    signed: bool  # it can match only signed frames


class RuleSet:
    """Rules compiled for `dialect` (RuleError, with the file, the line of `filter =` and the filter's caret,
    for a filter that does not compile), indexed by the message ids they can match."""

    def __init__(self, rules: Sequence[Rule], dialect: Dialect) -> None:
        self.dialect = dialect
        registry = FieldRegistry(dialect)
        problems: list[list[str]] = []
        compiled: list[Compiled] = []
        for r in rules:
            try:
                flt = compile_filter(r.filter, dialect, registry)
            except FilterError as exc:
                problems.append([f"{r.source}:{r.filter_line}: rule {r.id}: {exc.lines()[0]}", *exc.lines()[1:]])
                continue
            scope = filter_scope(r.filter, registry)
            compiled.append(Compiled(r, flt, scope.messages, scope.signed))
        if problems:
            raise RuleError(problems)
        self.rules = compiled
        self.by_message: dict[int, tuple[Compiled, ...]] = {}
        for c in compiled:
            for m in c.messages or ():
                self.by_message[m] = (*self.by_message.get(m, ()), c)
        # rules on any message: on every frame (`anywhere`), or on every signed frame (`signed`)
        self.anywhere = tuple(c for c in compiled if c.messages is None and not c.signed)
        self.signed = tuple(c for c in compiled if c.messages is None and c.signed)
        if self.anywhere:  # each message's rules, and those on every message, in the order given
            order = {id(c): k for k, c in enumerate(compiled)}
            self.by_message = {m: tuple(sorted((*cs, *self.anywhere), key=lambda c: order[id(c)]))
                               for m, cs in self.by_message.items()}
        self.vehicle = any(c.rule.when.vehicle for c in compiled)
        self.flight = any(c.rule.when.in_flight is not None for c in compiled)
        self.unsigned = any(c.rule.when.unsigned is not None for c in compiled)
        self.first = frozenset(m for c in compiled if c.rule.when.sender is not None for m in (c.messages or ()))
        if any(c.rule.when.sender is not None and c.messages is None for c in compiled):
            raise RuleError([[f"{c.rule.source}:{c.rule.line}: rule {c.rule.id}: `when.sender` needs a filter "
                              "that names its messages" for c in compiled
                              if c.rule.when.sender is not None and c.messages is None]])

    def __len__(self) -> int:
        return len(self.rules)


class _Hits:
    """One rule's matches: counted, the first frames kept, the first sender."""

    __slots__ = ("frames", "first", "counts", "given_up")

    def __init__(self, rule: Rule) -> None:
        self.frames = FrameNumbers(FRAMES_KEPT)
        self.first: tuple[int, int] | None = None
        self.counts: dict[Hashable, deque[float | None]] = {}
        self.given_up = GivenUp(f"rule {rule.id}: threshold counters ({MAX_KEYS:,} "
                                f"{rule.threshold.per.value if rule.threshold else 'sender'}s)", "counters")


class RuleEngine:
    """Evaluates a RuleSet over frames in capture order: `add(frame, fields)`, then `findings()`.

    `systems`: the analyses' `Systems` another analysis feeds with every HEARTBEAT (the audit's event log),
    read instead of a table of its own."""

    def __init__(self, rules: RuleSet, systems: Systems | None = None) -> None:
        self.set = rules
        self.state = VehicleState(rules.dialect, systems)
        self.links = SigningLinks()
        self.senders = FirstSenders(rules.first)
        self.hits: dict[str, _Hits] = {c.rule.id: _Hits(c.rule) for c in rules.rules}
        watched = {HEARTBEAT} if rules.vehicle and self.state.feeds else set()
        if rules.flight:
            watched |= {HEARTBEAT, EXTENDED_SYS_STATE, GLOBAL_POSITION_INT}
        self.watched = frozenset(watched) if rules.vehicle else frozenset()

    @property
    def reads(self) -> tuple[frozenset[int] | None, bool]:
        """The frames `add` reads (a caller that feeds frames in bulk gives it those alone): the message ids
        (None: every frame), and whether every signed frame too (the links' signing state, the rules on
        signature fields)."""
        if self.set.anywhere:
            return None, True
        return frozenset(self.set.by_message) | self.watched, bool(self.set.signed) or self.set.unsigned

    def add(self, f: Frame, fields: Fields | None = None) -> None:
        """Frame `f`; `fields`: its payload where the caller decoded it already."""
        if f.crc_status is not CrcStatus.OK:
            return
        msgid = f.msgid
        if self.set.unsigned and f.signature is not None:
            self.links.see(f)
        if msgid in self.watched:
            fields = decode_payload(f) if fields is None else fields
            if fields is not None:
                self.state.see(f, fields)
        rules = self.set.by_message.get(msgid, self.set.anywhere)
        if f.signature is not None and self.set.signed:
            rules = (*rules, *self.set.signed)
        if not rules:
            return
        first = self.senders.see(f) if msgid in self.set.first else None
        for c in rules:
            flt = c.filter
            if flt.needs_payload and fields is None:
                fields = decode_payload(f)
            if not flt.predicate(f, fields) or not self._conditions(c.rule, f, fields, first):
                continue
            self._hit(c.rule, f)

    def _conditions(self, r: Rule, f: Frame, fields: Fields | None, first: tuple[bool, bool] | None) -> bool:
        w = r.when
        if w.signature_ahead is not None:
            sig, t = f.signature, f.time
            if sig is None or t is None or sig.timestamp / 1e5 + SIGNING_EPOCH - t <= w.signature_ahead:
                return False
        if w.unsigned is not None and self.links.unsigned(f) is not w.unsigned:
            return False
        if w.sender is not None:
            if first is None or not first[0] or (w.sender is SenderState.NEW and not first[1]):
                return False
        if not w.vehicle:
            return True
        if fields is None:
            fields = decode_payload(f)
        return any(self._vehicle(w.armed, w.in_flight, w.modes, v, f.time) for v in self._vehicles(f, fields))

    def _vehicles(self, f: Frame, fields: Fields | None) -> Iterable[int]:
        """The vehicle a frame concerns: its target system, else its sender's system when that is a vehicle,
        else every vehicle heard."""
        for name in TARGET_FIELDS:
            t = fields.get(name) if fields is not None else None
            if isinstance(t, int) and t:
                return (t,)
        if f.sysid in self.state.systems.vehicles:
            return (f.sysid,)
        return self.state.vehicles()

    def _vehicle(self, armed: bool | None, in_flight: bool | None, modes: tuple[str, ...], sysid: int,
                 now: float | None) -> bool:
        hb = self.state.heartbeat(sysid)
        if hb is None:
            return False
        if armed is not None and hb.armed is not armed:
            return False
        if in_flight is not None and self.state.in_flight(sysid, now) is not in_flight:
            return False
        if modes:
            mode = (self.state.mode(sysid) or "").upper()
            if not any(mode == m or mode.startswith(m + ".") for m in modes):
                return False
        return True

    def _hit(self, r: Rule, f: Frame) -> None:
        h = self.hits[r.id]
        t = r.threshold
        if t is not None:
            key: Hashable = (f.sysid, f.compid) if t.per is Per.SENDER else link_of(f)
            q = h.counts.get(key)
            if q is None:
                q = h.counts[key] = deque(maxlen=t.count)
                if len(h.counts) > MAX_KEYS:
                    pop_newest(h.counts, key)
                    h.given_up.add(f"a {t.per.value}'s count dropped (a flood of {t.per.value}s may hide one that "
                                   "reaches the threshold)", record=f.record)
            q.append(f.time)
            now, oldest = f.time, q[0]
            if len(q) < t.count or (now is not None and oldest is not None and now - oldest > t.window):
                return
            q.clear()
        h.frames.add(f.record)
        if h.first is None:
            h.first = (f.sysid, f.compid)

    def findings(self) -> list[Finding]:
        """A finding per rule that matched (code `rule`, the rule's severity and id), and the `capacity`
        findings of the bounds that gave something up."""
        out: list[Finding] = []
        for c in self.set.rules:
            r, h = c.rule, self.hits[c.rule.id]
            if h.frames.count and h.first is not None:
                n = h.frames.count
                what = "time" if r.threshold is not None else "frame"
                many = f"{n:,} {what}{'s' if n != 1 else ''}"
                if r.threshold is not None:
                    many += (f" (at least {r.threshold.count:,} matches within {r.threshold.window:g} s per "
                             f"{r.threshold.per.value})")
                out.append(Finding("rule", r.severity, f"{r.title}: {many}, first from {h.first[0]}/{h.first[1]}",
                                   tuple(h.frames.nums), r.id))
            gave = h.given_up.finding()
            if gave is not None:
                out.append(gave)
        for bound in (self.links.given_up, self.senders.given_up):
            gave = bound.finding()
            if gave is not None:
                out.append(gave)
        return out


_pack: list[RuleSet] = []  # the shipped pack compiled for the Dialect last asked for


def pack_rules(dialect: Dialect) -> RuleSet:
    """The shipped pack compiled for `dialect` (once per Dialect)."""
    if not _pack or _pack[0].dialect is not dialect:
        _pack[:] = [RuleSet(load_rules(), dialect)]
    return _pack[0]


def rule_set(dialect: Dialect, paths: Sequence[str] = (), *, default: bool = True) -> RuleSet | None:
    """The shipped pack (unless `default` is False) and the rule files or directories `paths`, compiled for
    `dialect`; None when that is no rule at all."""
    if default and not paths:
        return pack_rules(dialect)
    rules = load_rules(paths, default=default)
    return RuleSet(rules, dialect) if rules else None
