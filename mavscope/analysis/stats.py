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
from itertools import islice

import numpy as np

from mavscope.analysis import expert_batch
from mavscope.analysis.expert import Expert
from mavscope.analysis.selection import Selection
from mavscope.analysis.sequence import Endpoints, SeqChannels, SeqTracker, totals
from mavscope.analysis.sequence_batch import Steps, feed_batch
from mavscope.mavlink.frame import Frame, signature_status
from mavscope.pipeline.batch import CRC_STATUSES, TRANSPORTS, VERDICTS, FrameBatch, Tables

RATE_BINS = 256  # a stream's frame times are counted in at most this many bins (bounded whatever the span)
RATE_MIN_FRAMES = 3  # a rate needs this many frames...
RATE_MIN_SPAN = 1.0  # ...over at least this many seconds; fewer seconds make a burst
# Rows followed at most. Links are at most 65,536 (one per sender), but a capture can name a new
# (sender, message) stream or a new pair of endpoints in every frame: 200,000 such frames held 590 MB.
# Frames of later streams and conversations count in the totals and their link, and as unfollowed.
MAX_STREAMS = 65_536
MAX_CONVERSATIONS = 65_536
BATCH = 4096  # frames per batch where frames come one by one (compute_stats)


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

    def _double(self) -> None:
        """Bins twice as wide: each pair of bins (from an even start) becomes one."""
        bins = self.bins
        self.width *= 2
        if self.start % 2:
            bins.insert(0, 0)
            self.start -= 1
        self.bins = [sum(bins[k : k + 2]) for k in range(0, len(bins), 2)]
        self.start //= 2

    def add(self, t: float) -> None:
        """One frame at `t`."""
        self.add_many(np.array([t], np.float64))

    def add_many(self, times: np.ndarray) -> None:
        """Frames at `times` (seconds). The bins are those frames added one by one would leave: the width
        doubles until the latest fits in RATE_BINS (floor(x / 2w) is floor(floor(x / w) / 2)), and the bins
        run from the earliest frame's to the latest's."""
        if not len(times):
            return
        ahead = times > self.origin
        span = float((times[ahead] - self.origin).max()) if ahead.any() else 0.0
        while int(span / self.width) >= RATE_BINS:
            self._double()
        i = np.where(ahead, np.floor((times - self.origin) / self.width), 0.0).astype(np.int64)
        lo, hi = int(i.min()), int(i.max())
        bins = self.bins
        if not bins:
            self.start = lo
        elif lo < self.start:
            bins[:0] = [0] * (self.start - lo)
            self.start = lo
        if hi - self.start >= len(bins):
            bins.extend([0] * (hi - self.start + 1 - len(bins)))
        counts = np.bincount(i - self.start)
        for j in np.flatnonzero(counts).tolist():
            bins[j] += int(counts[j])

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

    def add_batch(self, b: FrameBatch, steps: Steps | None = None) -> Steps:
        """The frames of batch `b`, in capture order: what `add`ing them one by one gave, counted per
        column (streams, links and conversations admitted in the order of their first frame). The
        sequence counters take them through `SeqChannels.feed_batch` unless `steps` (what it gave for
        this batch, where the caller fed them) is given. Returns the steps."""
        n = b.n
        if steps is None:
            steps = feed_batch(self.seqs, b)
        if not n:
            return steps
        self.total += n
        size = b.size.astype(np.int64)
        self.nbytes += int(size.sum())
        timed = np.flatnonzero(b.timed)
        if len(timed):
            if self.first is None:
                self.first = float(b.time[timed[0]])
            self.last = float(b.time[timed[-1]])
        sender = b.sender
        labels, texts = b.tables.labels, b.tables.texts
        self._streams(b, sender << 32 | b.label, size, labels)
        self._links(b, sender, size, texts)
        self._conversations(b, sender, size, texts)
        return steps

    def _streams(self, b: FrameBatch, key: np.ndarray, size: np.ndarray, labels: list[str]) -> None:
        for k, rows in _groups(key):
            s = int(k)
            skey = (s >> 40, (s >> 32) & 255, labels[s & 0xFFFFFFFF])
            st = self.streams.get(skey)
            if st is None and len(self.streams) < MAX_STREAMS:
                st = self.streams[skey] = _Stream()
            if st is None:
                self.unfollowed_streams += len(rows)
                continue
            st.count += len(rows)
            st.bytes += int(size[rows].sum())
            t = b.time[rows[b.timed[rows]]]
            if len(t):
                st.see(float(t[0]))
                st.last = float(t[-1])
                if st.rates is None:
                    st.rates = RateHistogram(self.first)  # type: ignore[arg-type]  # set with the first time
                st.rates.add_many(t)

    def _links(self, b: FrameBatch, sender: np.ndarray, size: np.ndarray, texts: list[str]) -> None:
        for k, rows in _groups(sender):
            key = (int(k) >> 8, int(k) & 255)
            lk = self.links.get(key)
            if lk is None:
                lk = self.links[key] = _Link()
                lk.channels = self.seqs.senders.setdefault(key, {})
            lk.received += len(rows)
            lk.bytes += int(size[rows].sum())
            v1 = int(np.count_nonzero(b.version[rows] == 1))
            lk.v1 += v1
            lk.v2 += len(rows) - v1
            for code, count in _counts(b.crc[rows]):
                status = CRC_STATUSES[code].value
                lk.crc[status] += count
                self.crc[status] += count
            for code, count in _counts(b.verdict[rows]):
                lk.signature[VERDICTS[code]] += count
                self.sigs[VERDICTS[code]] += count
            t = b.time[rows[b.timed[rows]]]
            if len(t):
                lk.see(float(t[0]))
                lk.last = float(t[-1])
            src = b.src[rows]
            lk.endpoints.update(texts[e] for e in np.unique(src[src >= 0]).tolist())
        for code, count in _counts(b.version):
            self.versions[code] += count

    def _conversations(self, b: FrameBatch, sender: np.ndarray, size: np.ndarray, texts: list[str]) -> None:
        route = (b.transport.astype(np.int64) << 50) | ((b.src.astype(np.int64) + 1) << 25) | (b.dst + 1)
        routes = _groups(route)
        conv = np.empty(b.n, np.int64)  # per row: its conversation's place in `found` (-1: unfollowed)
        ahead = np.empty(b.n, np.bool_)  # per row: from the conversation's `a`
        found: list[_Conversation] = []
        where: dict[tuple[str, str, str], int] = {}
        for k, rows in routes:  # in the order of their first frame, as conversations are admitted
            transport = TRANSPORTS[k >> 50]
            src, dst = ((k >> 25) & 0x1FFFFFF) - 1, (k & 0x1FFFFFF) - 1
            a, z = texts[src] if src >= 0 else transport, texts[dst] if dst >= 0 else ""
            ck = (transport, a, z) if a <= z else (transport, z, a)
            j = where.get(ck)
            if j is None:
                c = self.convs.get(ck)
                if c is None and len(self.convs) < MAX_CONVERSATIONS:
                    c = self.convs[ck] = _Conversation(ck[1], ck[2], transport)
                j = where[ck] = -1 if c is None else len(found)
                if c is not None:
                    found.append(c)
            conv[rows] = j
            ahead[rows] = j >= 0 and a == found[j].a
        self.unfollowed_conversations += int(np.count_nonzero(conv < 0))
        for j, rows in _groups(conv):
            if j < 0:
                continue
            c = found[j]
            ab = ahead[rows]
            n_ab = int(np.count_nonzero(ab))
            c.frames_ab += n_ab
            c.frames_ba += len(rows) - n_ab
            c.bytes_ab += int(size[rows[ab]].sum())
            c.bytes_ba += int(size[rows[~ab]].sum())
            t = b.time[rows[b.timed[rows]]]
            if len(t):
                c.see(float(t[0]))
                c.last = float(t[-1])
            c.systems.update((s >> 8, s & 255) for s in np.unique(sender[rows]).tolist())

    def result(self) -> Stats:
        return Stats(self.streams, self.links, self.convs, self.total, self.nbytes, self.first, self.last, self.crc,
                     self.versions, self.sigs, self.unfollowed_streams, self.unfollowed_conversations)


def compute_stats(frames: Iterable[Frame], expert: Expert | None = None) -> Stats:
    """The statistics of `frames` (in capture order), in batches of BATCH frames. With `expert`, which is
    given every frame too, the senders it finds logged in part (`Expert.logged_in_part`) are marked
    (`Stats.logged_in_part`): `stats` gives it every detector (its findings), the TUI's statistics screen
    those that verdict reads."""
    builder = StatsBuilder()
    tables = Tables()
    for chunk in batched(frames, BATCH):
        b = FrameBatch.of_frames(chunk, tables)
        steps = builder.add_batch(b)
        if expert is not None:
            expert_batch.feed(expert, b, steps)
    stats = builder.result()
    if expert is not None:
        stats.logged_in_part = expert.logged_in_part()
    return stats


def batched(items: Iterable[Frame], n: int) -> Iterable[list[Frame]]:
    """`items` in lists of `n` (the last shorter)."""
    it = iter(items)
    while chunk := list(islice(it, n)):
        yield chunk


def _groups(keys: np.ndarray) -> list[tuple[int, np.ndarray]]:
    """(key, its rows ascending) per distinct key, in the order of each key's first row."""
    if not len(keys):
        return []
    order = np.argsort(keys, kind="stable")
    ordered = keys[order]
    cut = np.flatnonzero(ordered[1:] != ordered[:-1]) + 1
    starts = np.concatenate(([0], cut))
    groups = np.split(order, cut)
    firsts = order[starts]
    return [(int(ordered[starts[g]]), groups[g]) for g in np.argsort(firsts, kind="stable").tolist()]


def _counts(codes: np.ndarray) -> list[tuple[int, int]]:
    """(code, how many rows hold it) for each code present, ascending."""
    counts = np.bincount(codes)
    return [(int(c), int(counts[c])) for c in np.flatnonzero(counts)]
