"""Link statistics: per message stream, per link (sysid, compid), per conversation, and totals.

`StatsBuilder.add(frame)` takes every frame in capture order (`compute_stats(frames)` in one call) and
`result()` gives a `Stats` whose `to_json(selection)` is the `mavscope stats --json` document
(docs/analysis.md): under a display filter, the rows with a matched frame, computed over every frame.
No presentation here: the command renders the tables and sparklines.

Loss comes from sequence gaps per (sysid, compid) and channel (`SeqChannels`: the frame's source and
destination endpoints, for MAVLink counts per channel), modulo 256 (`SeqTracker`): a frame whose sequence
number is ahead of the last one by d counts d - 1 lost; the same number again is a duplicate; a number
behind (by up to 128) is a late frame: it fills a gap already counted (loss - 1, `reordered`) or, if no
gap holds it, is a duplicate. Gaps of more than 127 cannot be told from late frames and count as late.
A link's row sums its channels. A ground station's frames in a tlog are logged only in part (the tlog holds
what it received): its row says so (`logged_in_part`), and the totals count its missing numbers apart
(`lost_logged_in_part`, part of `lost`), not as link loss.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, field

from mavscope.analysis.expert import Expert
from mavscope.analysis.selection import Selection
from mavscope.analysis.sequence import Endpoints, SeqChannels, SeqTracker, totals
from mavscope.mavlink.frame import Frame, signature_status
from mavscope.mavlink.semantics import message_label

RATE_BINS = 256  # a stream's frame times are counted in at most this many bins (bounded whatever the span)
RATE_MIN_FRAMES = 3  # a rate needs this many frames...
RATE_MIN_SPAN = 1.0  # ...over at least this many seconds; fewer seconds make a burst
# Rows followed at most. Links are at most 65,536 (one per sender), but a capture can name a new
# (sender, message) stream or a new pair of endpoints in every frame: 200,000 such frames held 590 MB.
# Frames of later streams and conversations count in the totals and their link, and as unfollowed.
MAX_STREAMS = 65_536
MAX_CONVERSATIONS = 65_536


@dataclass(kw_only=True)
class _Timed:
    """The capture times of the first and last frame seen."""

    first: float | None = None
    last: float | None = None

    def see(self, t: float | None) -> None:
        if t is not None:
            if self.first is None:
                self.first = t
            self.last = t


class RateHistogram:
    """Frames counted in time bins from `origin`: at most RATE_BINS bins, whose width (1 s at first)
    doubles whenever a frame falls beyond them, so memory stays bounded whatever the capture's span (two
    records 56 years apart make 35 doublings, not 1.8e9 seconds). `bins` holds bin `start` onwards: a stream
    that begins late in the capture keeps no empty bins before its first frame (65,000 streams of a few
    frames each would otherwise hold 256 bins apiece)."""

    __slots__ = ("origin", "width", "start", "bins")

    def __init__(self, origin: float) -> None:
        self.origin = origin
        self.width = 1.0
        self.start = 0
        self.bins: list[int] = []

    def add(self, t: float) -> None:
        i = int((t - self.origin) / self.width) if t > self.origin else 0
        bins = self.bins
        while i >= RATE_BINS:
            self.width *= 2
            if self.start % 2:
                bins.insert(0, 0)
                self.start -= 1
            bins = self.bins = [sum(bins[k : k + 2]) for k in range(0, len(bins), 2)]
            self.start //= 2
            i //= 2
        if not bins:
            self.start = i
        elif i < self.start:
            bins[:0] = [0] * (self.start - i)
            self.start = i
        j = i - self.start
        if j >= len(bins):
            bins.extend([0] * (j + 1 - len(bins)))
        bins[j] += 1

    def series(self, span: float, buckets: int) -> list[float]:
        """Frames per second in at most `buckets` equal slices of `span` seconds from the origin, each slice
        the average of the bins it holds (fewer slices when the span holds fewer bins)."""
        nbins = max(1, min(RATE_BINS, int(span / self.width) + 1))
        n = max(1, min(buckets, nbins))
        counts = [0] * n
        widths = [0] * n
        start, end = self.start, self.start + len(self.bins)
        for i in range(nbins):
            k = i * n // nbins
            widths[k] += 1
            if start <= i < end:
                counts[k] += self.bins[i - start]
        return [c / (w * self.width) for c, w in zip(counts, widths)]


@dataclass
class _Stream(_Timed):
    count: int = 0
    bytes: int = 0
    rates: RateHistogram | None = None


@dataclass
class _Link(_Timed):
    received: int = 0
    bytes: int = 0
    v1: int = 0
    v2: int = 0
    crc: Counter[str] = field(default_factory=Counter)
    signature: Counter[str] = field(default_factory=Counter)
    channels: dict[Endpoints, SeqTracker] = field(default_factory=dict)  # the sender's, by channel
    endpoints: set[str] = field(default_factory=set)


@dataclass
class _Conversation(_Timed):
    a: str
    b: str
    transport: str
    frames_ab: int = 0
    frames_ba: int = 0
    bytes_ab: int = 0
    bytes_ba: int = 0
    systems: set[tuple[int, int]] = field(default_factory=set)


def _span(first: float | None, last: float | None) -> float | None:
    return None if first is None or last is None else last - first


def _rate(s: _Stream) -> tuple[float | None, bool]:
    """(frames per second, burst): no rate from fewer than RATE_MIN_FRAMES frames; frames that all came
    within RATE_MIN_SPAN seconds are a burst, not a rate (3 MISSION_CLEAR_ALL in 1 ms are not 2000 Hz)."""
    span = _span(s.first, s.last)
    if s.count < 2 or span is None:
        return None, False
    if span < RATE_MIN_SPAN:
        return None, True
    if s.count < RATE_MIN_FRAMES:
        return None, False
    return (s.count - 1) / span, False


def signature_verdict(frame: Frame) -> str:
    """`unsigned`, or the signature status (no-key without key material)."""
    status = signature_status(frame.incompat_flags, frame.security)
    return "unsigned" if status is None else status.value


@dataclass
class Stats:
    streams: dict[tuple[int, int, str], _Stream]
    links: dict[tuple[int, int], _Link]
    conversations: dict[tuple[str, str, str], _Conversation]
    frames: int
    bytes: int
    first: float | None
    last: float | None
    crc: Counter[str]
    versions: Counter[int]
    signature: Counter[str]
    unfollowed_streams: int = 0  # frames of (sender, message) streams beyond the first MAX_STREAMS
    unfollowed_conversations: int = 0  # frames of conversations beyond the first MAX_CONVERSATIONS
    # senders whose own frames the capture logs only in part (ground stations in a tlog: Expert.logged_in_part,
    # which the command sets): their `lost` is said to be no link loss, and totalled apart
    logged_in_part: frozenset[tuple[int, int]] = frozenset()

    @property
    def duration(self) -> float | None:
        return _span(self.first, self.last)

    def messages_json(self, select: Selection | None = None) -> list[dict[str, object]]:
        out = []
        for (sysid, compid, name), s in sorted(self.streams.items()):
            if select is not None and not select.stream((sysid, compid, name)):
                continue
            rate, burst = _rate(s)
            out.append({"sysid": sysid, "compid": compid, "msgname": name, "count": s.count,
                        "rate_hz": None if rate is None else round(rate, 4), "burst": burst, "bytes": s.bytes,
                        "first": s.first, "last": s.last})
        return out

    def links_json(self, select: Selection | None = None) -> list[dict[str, object]]:
        out = []
        for (sysid, compid), lk in sorted(self.links.items()):
            if select is not None and not select.link((sysid, compid)):
                continue
            seq = totals(lk.channels.values())
            expected = lk.received - seq.duplicates - seq.unchanged + seq.lost
            out.append({
                "sysid": sysid, "compid": compid, "received": lk.received, "lost": seq.lost,
                "loss_pct": round(100.0 * seq.lost / expected, 3) if expected > 0 else 0.0,
                "logged_in_part": (sysid, compid) in self.logged_in_part,
                "duplicates": seq.duplicates, "unchanged_seq": seq.unchanged, "reordered": seq.reordered,
                "bytes": lk.bytes,
                "v1": lk.v1, "v2": lk.v2, "crc": dict(sorted(lk.crc.items())),
                "signature": dict(sorted(lk.signature.items())), "first": lk.first, "last": lk.last,
                "endpoints": sorted(lk.endpoints),
            })
        return out

    def conversations_json(self, select: Selection | None = None) -> list[dict[str, object]]:
        out = []
        for c in sorted(self.conversations.values(), key=lambda c: (c.first or 0.0, c.a, c.b)):
            if select is not None and not any(select.link(s) for s in c.systems):
                continue
            out.append({
                "transport": c.transport, "a": c.a, "b": c.b, "frames": c.frames_ab + c.frames_ba,
                "bytes": c.bytes_ab + c.bytes_ba, "frames_a_to_b": c.frames_ab, "frames_b_to_a": c.frames_ba,
                "bytes_a_to_b": c.bytes_ab, "bytes_b_to_a": c.bytes_ba, "start": c.first,
                "duration": _span(c.first, c.last),
                "systems": [list(s) for s in sorted(c.systems)],
            })
        return out

    def totals_json(self) -> dict[str, object]:
        return {
            "frames": self.frames, "bytes": self.bytes, "start": self.first, "duration": self.duration,
            "links": len(self.links), "messages": len({k[2] for k in self.streams}),
            "lost": sum(totals(lk.channels.values()).lost for lk in self.links.values()),
            "lost_logged_in_part": sum(totals(lk.channels.values()).lost for key, lk in self.links.items()
                                       if key in self.logged_in_part),
            "v1": self.versions.get(1, 0), "v2": self.versions.get(2, 0),
            "crc": dict(sorted(self.crc.items())), "signature": dict(sorted(self.signature.items())),
            "unfollowed_stream_frames": self.unfollowed_streams,
            "unfollowed_conversation_frames": self.unfollowed_conversations,
        }

    def to_json(self, select: Selection | None = None) -> dict[str, object]:
        """The `stats --json` document: the rows `select` selects (all without it), totals of every frame."""
        totals = self.totals_json()
        if select is not None and select.active:
            totals["matched"] = select.matched
        return {"messages": self.messages_json(select), "links": self.links_json(select),
                "conversations": self.conversations_json(select), "totals": totals}

    def rate_series(self, key: tuple[int, int, str], buckets: int) -> list[float]:
        """Frames per second of one stream in at most `buckets` equal slices of the capture (a sparkline)."""
        rates = self.streams[key].rates
        if self.first is None or self.last is None or rates is None:
            return []
        return rates.series(self.last - self.first, buckets)


class StatsBuilder:
    """Statistics accumulated one frame at a time (`add`), in bounded state per stream, link and
    conversation; `result()` gives the `Stats`."""

    def __init__(self) -> None:
        self.streams: dict[tuple[int, int, str], _Stream] = {}
        self.links: dict[tuple[int, int], _Link] = {}
        self.convs: dict[tuple[str, str, str], _Conversation] = {}
        self.seqs = SeqChannels()
        self.crc: Counter[str] = Counter()
        self.versions: Counter[int] = Counter()
        self.sigs: Counter[str] = Counter()
        self.total = 0
        self.nbytes = 0
        self.first: float | None = None
        self.last: float | None = None
        self.unfollowed_streams = 0
        self.unfollowed_conversations = 0

    def add(self, f: Frame) -> None:
        self.total += 1
        size = len(f.raw)
        self.nbytes += size
        t = f.time
        if t is not None:
            if self.first is None:
                self.first = t
            self.last = t
        name = message_label(f.msgid, f.msgdef)
        key = (f.sysid, f.compid, name)
        s = self.streams.get(key)
        if s is None and len(self.streams) < MAX_STREAMS:
            s = self.streams[key] = _Stream()
        if s is None:
            self.unfollowed_streams += 1
        else:
            s.count += 1
            s.bytes += size
            s.see(t)
            if t is not None:
                if s.rates is None:
                    s.rates = RateHistogram(self.first)  # type: ignore[arg-type]  # set with the first time
                s.rates.add(t)
        lk = self.links.get(key[:2])
        if lk is None:
            lk = self.links[key[:2]] = _Link()
            lk.channels = self.seqs.senders.setdefault(key[:2], {})
        lk.received += 1
        lk.bytes += size
        if f.version == 1:
            lk.v1 += 1
        else:
            lk.v2 += 1
        status = f.crc_status.value
        lk.crc[status] += 1
        self.crc[status] += 1
        self.versions[f.version] += 1
        verdict = signature_verdict(f)
        lk.signature[verdict] += 1
        self.sigs[verdict] += 1
        self.seqs.feed(f)
        lk.see(t)
        if f.src is not None:
            lk.endpoints.add(f.src.text)
        a, b = str(f.src or f.transport), str(f.dst or "")
        ck = (f.transport, a, b) if a <= b else (f.transport, b, a)
        c = self.convs.get(ck)
        if c is None:
            if len(self.convs) >= MAX_CONVERSATIONS:
                self.unfollowed_conversations += 1
                return
            c = self.convs[ck] = _Conversation(ck[1], ck[2], f.transport)
        if a == c.a:
            c.frames_ab += 1
            c.bytes_ab += size
        else:
            c.frames_ba += 1
            c.bytes_ba += size
        c.see(t)
        c.systems.add(key[:2])

    def result(self) -> Stats:
        return Stats(self.streams, self.links, self.convs, self.total, self.nbytes, self.first, self.last, self.crc,
                     self.versions, self.sigs, self.unfollowed_streams, self.unfollowed_conversations)


def compute_stats(frames: Iterable[Frame], expert: Expert | None = None) -> Stats:
    """The statistics of `frames` (in capture order). With `expert`, which is given every frame too, the
    senders it finds logged in part (`Expert.logged_in_part`) are marked (`Stats.logged_in_part`): `stats`
    gives it every detector (its findings), the TUI's statistics screen those that verdict reads."""
    builder = StatsBuilder()
    if expert is None:
        for f in frames:
            builder.add(f)
        return builder.result()
    for f in frames:
        builder.add(f)
        expert.add(f)
    stats = builder.result()
    stats.logged_in_part = expert.logged_in_part()
    return stats
