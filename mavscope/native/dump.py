"""The `stats` accumulator's state, read back into Python objects (for `stats` and the export's findings).

The C accumulator (src/mavscope_native/acc.h: StatsBuilder and the expert detectors that see every
frame, ported step for step) is fed by the walker's clean frames and, through `add_frame`, by the frames
of every record the walker hands back, in capture order. `rebuild` turns its `dump()` (layout in
acc_dump.c) into the very objects the pure path builds (Stats with its _Stream, _Link, _Conversation,
RateHistogram, SeqTracker; the Expert's detectors), whose own code writes the rows, the JSON and the
findings' sentences. `plan_for` compiles what the accumulator needs of a dialect (native_plan).
"""

from __future__ import annotations

import struct
from collections import Counter
from collections.abc import Iterable
from typing import Any, TypeVar

from mavscope.analysis import commanders, control, gnss
from mavscope.analysis.commanders import Commanded, CommandSources
from mavscope.analysis.expert import (
    BadCrcBursts,
    Expert,
    HiddenFrames,
    KeyLeaks,
    ReplayedCommands,
    SequenceAnomalies,
    UnsignedCommands,
)
from mavscope.analysis.framelist import frame_numbers
from mavscope.analysis.sequence import SHARED, Gap, SeqTracker
from mavscope.analysis.stats import RateHistogram, Stats, _Conversation, _Link, _Stream, signature_verdict
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus, Frame, SignatureStatus, plaintext_payload
from mavscope.mavlink.semantics import message_label
from mavscope.native.core import STATS_TRANSPORTS
from mavscope.native.plan import build_plan
from mavscope.notes import FrameNumbers
from mavscope.transport.base import TRANSPORT_TLOG

TRANSPORTS = STATS_TRANSPORTS  # Stats.add's transport codes (the extension's STATS_TRANSPORT_*)
CRC = tuple(CrcStatus)  # MS_CRC_*: ok, bad, unchecked, truncated
SIGNATURES = ("unsigned", *(s.value for s in (SignatureStatus.VALID, SignatureStatus.INVALID, SignatureStatus.NO_KEY,
                                              SignatureStatus.REPLAY, SignatureStatus.TRUNCATED)))  # MS_SIG_*
SEQ_EVENTS = ("duplicate", "late", "unchanged")
LABEL_COMMAND = 0x40000000  # control.c: a label that is a command's name
LABEL_UNKNOWN = 0x80000000  # expert.c: str(msgid) of an unknown message
GNSS_CODES = ("gnss-position-jump", "gnss-fix-collapse", "ekf-gnss-alarm", "gnss-time-jump")  # MS_GC_*
EPISODE_TEXT = 0x80  # acc.h MS_EPISODE_TEXT
GNSS_MESSAGES = ("GLOBAL_POSITION_INT", "GPS_RAW_INT", "GPS2_RAW", "SYSTEM_TIME", "EKF_STATUS_REPORT",
                 "ESTIMATOR_STATUS")  # MS_G_*

T = TypeVar("T")
_plans: list[tuple[Dialect, bytes | None]] = []  # the last Dialect compiled and its plan


def plan_for(dialect: Dialect) -> bytes | None:
    """The plan of `dialect` (native_plan.build_plan), compiled once for the Dialect object last asked for."""
    if not _plans or _plans[0][0] is not dialect:
        _plans[:] = [(dialect, build_plan(dialect))]
    return _plans[0][1]


class Accumulator:
    """A `_native.Stats` the walker feeds, and what the Python side adds to it: the frames of the records
    handed back (`add`, in capture order) and the detectors only such frames can feed (BadCrcBursts: bad
    CRCs; KeyLeaks: SETUP_SIGNING and key material the walker never takes; HiddenFrames: the framer's notes)."""

    def __init__(self, acc: Any) -> None:
        self.acc = acc
        self.bursts, self.leaks, self.hidden = BadCrcBursts(), KeyLeaks(), HiddenFrames()
        self.frames = 0  # frames added

    def add(self, f: Frame) -> None:
        src, dst = f.src, f.dst
        self.acc.add(f.record, f.time, TRANSPORTS.index(f.transport), None if src is None else src.text,
                     None if dst is None else dst.text, f.raw, f.version, f.seq, f.sysid, f.compid, f.msgid,
                     f.msgdef is not None, CRC.index(f.crc_status), SIGNATURES.index(signature_verdict(f)),
                     f.signature is not None, plaintext_payload(f))
        self.bursts.add(f, None)
        self.leaks.add(f, None)
        self.hidden.add(f, None)
        self.frames += 1

    def full(self) -> bool:
        """Whether a table of the accumulator reached a cap the Python classes do not have (acc.h MS_CAP_*):
        its state is then incomplete, and the pure path must run instead."""
        return bool(self.acc.full())

    def result(self, dialect: Dialect) -> tuple[Stats, Expert]:
        """The Stats and the Expert of everything accumulated (not `full`). The accumulator is let go once
        dumped (its C state freed, when the walker that was fed from it is gone too), so that the C tables
        and the Python objects rebuilt from them are not held at once: about 5 KB a sender each, 330 MB of C
        state on a capture naming 62,000 senders."""
        dump = self.acc.dump()
        self.acc = None
        stats, ex = rebuild(dump, dialect)
        ex.recorded = any(c.transport == TRANSPORT_TLOG for c in stats.conversations.values())  # as Expert.add
        ex.detectors[ex.detectors.index(_one(ex, BadCrcBursts))] = self.bursts
        ex.detectors[ex.detectors.index(_one(ex, KeyLeaks))] = self.leaks
        ex.detectors[ex.detectors.index(_one(ex, HiddenFrames))] = self.hidden
        return stats, ex


def _one(ex: Expert, cls: type[T]) -> T:
    """The Expert's detector of class `cls`."""
    return next(d for d in ex.detectors if type(d) is cls)


class _Reader:
    """The dump of acc_dump.c, read in order (`strings`: its interned texts, by id)."""

    def __init__(self, data: bytes) -> None:
        self.data = data
        self.pos = 0
        self.strings: list[str] = []

    def take(self, fmt: str) -> tuple[Any, ...]:
        values = struct.unpack_from("<" + fmt, self.data, self.pos)
        self.pos += struct.calcsize("<" + fmt)
        return values

    def one(self, fmt: str) -> int:
        return int(self.take(fmt)[0])

    def bytes(self, n: int) -> bytes:
        out = self.data[self.pos : self.pos + n]
        self.pos += n
        return out

    def frames(self) -> FrameNumbers:
        count, n = self.take("QI")
        fn = frame_numbers()
        fn.nums = list(self.take(f"{n}Q"))
        fn.count = count
        return fn

    def pairs(self) -> list[tuple[int, int, int]]:
        return [self.take("IIQ") for _ in range(self.one("I"))]

    def ints(self) -> list[int]:
        return list(self.take(f"{self.one('I')}i"))


def _timed(has: int, first: float, last: float) -> tuple[float | None, float | None]:
    """(first, last) of a timed row: None where it saw no time."""
    return (first, last) if has else (None, None)


def _counter(names: Iterable[str], counts: Iterable[int]) -> Counter[str]:
    return Counter({n: c for n, c in zip(names, counts) if c})


def rebuild(dump: bytes, dialect: Dialect) -> tuple[Stats, Expert]:
    """The Stats and the Expert (its detectors' state) of an accumulator's dump."""
    r = _Reader(dump)
    if r.bytes(4) != b"MSSD" or r.one("I") != 4:
        raise ValueError("not a statistics dump")
    total, nbytes, has_first, first, last = r.take("QQBdd")
    crc = _counter((c.value for c in CRC), r.take("4Q"))
    sigs = _counter(SIGNATURES, r.take("6Q"))
    v1, v2, unfollowed_streams, unfollowed_convs = r.take("QQQQ")
    strings = r.strings = [r.bytes(r.one("I")).decode() for _ in range(r.one("I"))]
    origin = first if has_first else None

    def label(msgid: int) -> str:
        return message_label(msgid, dialect.messages.get(msgid))

    streams: dict[tuple[int, int, str], _Stream] = {}
    for _ in range(r.one("I")):
        key, count, size, has, s_first, s_last, has_rates, width, nbins = r.take("QQQBddBdI")
        stream = _Stream(count=count, bytes=size)
        stream.first, stream.last = _timed(has, s_first, s_last)
        bins = list(r.take(f"{nbins}Q"))
        if has_rates:
            stream.rates = RateHistogram(origin)  # type: ignore[arg-type]  # set with the first time
            stream.rates.width, stream.rates.bins = width, bins
        streams[(key >> 32, (key >> 24) & 0xFF, label(key & 0xFFFFFF))] = stream
    ends = {-1: "", -2: SHARED[0]}
    links: dict[tuple[int, int], _Link] = {}
    events_of: list[tuple[tuple[int, int], tuple[int, int, int]]] = []
    for _ in range(r.one("I")):
        sender, received, size, lv1, lv2 = r.take("HQQQQ")
        lk = _Link(received=received, bytes=size, v1=lv1, v2=lv2, crc=_counter((c.value for c in CRC), r.take("4Q")),
                   signature=_counter(SIGNATURES, r.take("6Q")))
        lk.first, lk.last = _timed(*r.take("Bdd"))
        addr = (sender >> 8, sender & 0xFF)
        events_of.append((addr, r.take("3i")))
        for _ in range(r.one("I")):
            src, dst, lost, dup, rep, unch, reord, shared, full, steps, first_full, partner, large, ngaps = \
                r.take("iiqqqqqqqqqiQB")
            tr = SeqTracker(lost=lost, duplicates=dup, repeats=rep, unchanged=unch, reordered=reord,
                            large_gaps=large, shared=shared, full_steps=full, gap_steps=steps, partner=partner,
                            first_full=first_full)
            tr.gaps = [Gap(*r.take("QBBBBB")) for _ in range(ngaps)]
            lk.channels[(strings[src] if src >= 0 else ends[src], strings[dst] if dst >= 0 else ends[dst])] = tr
        links[addr] = lk
    for lk in links.values():  # each tracker's mate: its partner's tracker on the same channel
        for chan, tr in lk.channels.items():
            if tr.partner >= 0 and (mate := links.get((tr.partner >> 8, tr.partner & 0xFF))) is not None:
                tr.mate = mate.channels.get(chan)
    addrs = list(links)
    for owner, value, _count in r.pairs():
        links[addrs[owner]].endpoints.add(strings[value])
    convs: dict[tuple[str, str, str], _Conversation] = {}
    for _ in range(r.one("I")):
        transport, a, b, fab, fba, bab, bba, has, c_first, c_last = r.take("BiiQQQQBdd")
        tname = TRANSPORTS[transport]
        conv = convs[(tname, strings[a], strings[b])] = _Conversation(
            strings[a], strings[b], tname, frames_ab=fab, frames_ba=fba, bytes_ab=bab, bytes_ba=bba)
        conv.first, conv.last = _timed(has, c_first, c_last)
    keys = list(convs)
    for owner, value, _count in r.pairs():
        convs[keys[owner]].systems.add((value >> 8, value & 0xFF))
    stats = Stats(streams, links, convs, total, nbytes, first if has_first else None, last if has_first else None,
                  crc, Counter({v: n for v, n in ((1, v1), (2, v2)) if n}), sigs, unfollowed_streams, unfollowed_convs)
    return stats, _experts(r, dialect, links, events_of)


def _experts(r: _Reader, dialect: Dialect, links: dict[tuple[int, int], _Link],
             events_of: list[tuple[tuple[int, int], tuple[int, int, int]]]) -> Expert:
    """The Expert's detectors with the state the accumulator holds (the rest of the dump)."""
    ex = Expert(dialect)
    seq = _one(ex, SequenceAnomalies)
    assert isinstance(seq, SequenceAnomalies)
    for addr, lk in links.items():
        seq.seqs.senders[addr] = lk.channels
        seq.counts[addr] = lk.received
    events = [((sender >> 8, sender & 0xFF), SEQ_EVENTS[what], fn)
              for sender, what, fn in ((r.one("H"), r.one("B"), r.frames()) for _ in range(r.one("I")))]
    for addr, what, fn in events:
        seq.events[(addr, what)] = fn
    event_labels = r.pairs()
    named = [(r.take("IqQ"), r.frames()) for _ in range(r.one("I"))]
    names: list[list[tuple[int, int]]] = [[] for _ in named]
    for owner, value, count in r.pairs():
        names[owner].append((value, count))
    copies, replays, candidates, intrusions = r.ints(), r.ints(), r.ints(), r.ints()
    ctl = _one(ex, control.ControlSources)
    assert isinstance(ctl, control.ControlSources)

    def label(code: int) -> str:
        if code & LABEL_UNKNOWN:
            return str(code & 0xFFFFFF)
        if code & LABEL_COMMAND:
            return ctl._command_name(code & 0xFFFF)
        return dialect.messages[code].name

    def counted(i: int) -> Counter[str]:
        out: Counter[str] = Counter()
        for code, count in names[i]:
            out[label(code)] += count
        return out

    for owner, code, count in event_labels:
        addr, what, _ = events[owner]
        seq.messages.setdefault((addr, what), Counter())[label(code)] += count
    rep = _one(ex, ReplayedCommands)
    assert isinstance(rep, ReplayedCommands)
    for table, order in ((rep.copies, copies), (rep.replays, replays)):
        for i in order:
            key = named[i][0][0]
            table[(key >> 8, key & 0xFF)] = (named[i][1], counted(i))
    uns = _one(ex, UnsignedCommands)
    assert isinstance(uns, UnsignedCommands)
    signing = r.bytes(32)
    uns.signing = {v for v in range(256) if signing[v >> 3] >> (v & 7) & 1}
    for i in candidates:
        key = named[i][0][0]
        ckey = (key >> 17, (key >> 9) & 0xFF, (key & 0x1FF) - 1)
        uns.candidates[ckey] = named[i][1]
        uns.names[ckey] = counted(i)
    cs = _one(ex, CommandSources)
    assert isinstance(cs, CommandSources)
    gcs = r.bytes(32)
    cs.gcs = {v for v in range(256) if gcs[v >> 3] >> (v & 7) & 1}
    strings = r.strings
    for _ in range(r.one("I")):
        kind, target, sender, msgid, a, b, record = r.take("BBHIiiQ")
        addr, name = (sender >> 8, sender & 0xFF), dialect.messages[msgid].name
        if kind == 1:
            cs.out.append((target, commanders.unexpected_command_source(addr, name, strings[a], strings[b], record)))
        else:
            cs.out.append((target, commanders.command_without_heartbeat(addr, name, target, record)))
    for _ in range(r.one("I")):
        target, first, nshown = r.take("BHB")
        c = cs.commanded[target] = Commanded((first >> 8, first & 0xFF))
        for _ in range(nshown):
            sender, msgid = r.take("HI")
            c.shown.append(((sender >> 8, sender & 0xFF), dialect.messages[msgid].name))
        c.frames = r.frames()
    for _ in range(r.one("I")):
        kind, vehicle, sender, holder, flag, why, code, record, since, asked, alt = r.take("BBBBBBIQQQd")
        old = r.bytes(r.one("H")).decode()
        new = r.bytes(r.one("H")).decode()
        if kind == 0:
            ctl.out.append(control.mission_clear(sender, vehicle, bool(flag), record, holder, since))
        elif kind == 1:
            ctl.out.append(control.mode_change(vehicle, old, new, record, label(code), sender, asked, holder))
        else:
            reason = control.landed_why(code) if why else control.altitude_why(alt)
            ctl.out.append(control.in_flight_disarm(vehicle, reason, record, (sender, asked) if flag else None))
    for i in intrusions:
        key = named[i][0][0]
        messages: dict[str, int] = {}
        for code, count in names[i]:
            messages[label(code)] = messages.get(label(code), 0) + count
        ctl.intrusions[(key >> 8, key & 0xFF)] = control._Intrusions(
            frames=named[i][1], messages=messages, holder=named[i][0][1], since=named[i][0][2])
    gn = _one(ex, gnss.GnssAnomalies)
    assert isinstance(gn, gnss.GnssAnomalies)
    for _ in range(r.one("I")):
        code, g, sender, flags = r.take("BBHB")
        fn = r.frames()
        worst, a0, a1, a2, a3, n0, n1, n2, n3 = r.take("d4d4q")
        msg = GNSS_MESSAGES[g]
        if not flags & EPISODE_TEXT:
            text = ""  # no size above the initial worst (-1.0): no sentence
        elif code == 0:
            text = gnss.jump_text(a0, a1, a2, n0, n1, a3)
        elif code == 1:
            text = gnss.collapse_text(n0, n1 if flags & 1 else None, n2, a0, n3)
        elif code == 2:
            text = gnss.ekf_text(gnss.ekf_reasons(bool(flags & 1), bool(flags & 2), a0 if flags & 4 else None), n0, n1)
        elif flags & 2:
            text = gnss.gps_time_text(msg, a0, n0, n1)
        else:
            text = gnss.time_jump_text(a0, n0, n1, a1 if flags & 1 else None)
        gn.found[(GNSS_CODES[code], (sender >> 8, sender & 0xFF), msg)] = gnss._Episodes(fn, worst, text)
    if r.pos != len(r.data):
        raise ValueError("statistics dump longer than read")
    return ex

