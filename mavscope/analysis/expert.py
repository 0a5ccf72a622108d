"""Expert findings built from the frames of a capture (Wireshark's expert info, one level up).

Each detector is an accumulator: `add(frame, fields)` once per frame in capture order (`fields` is the
decoded payload of a commanding or HEARTBEAT frame, else None), then `findings()`. Detectors keep
bounded state, so a capture of any length is analysed in one pass without holding its frames.
`Expert` runs a set of them (`DETECTORS` by default; the TUI and the audit may pick their own), and
`expert_findings(frames, dialect)` is the one-call form. Codes and severities come from the registry in
`mavscope.notes`; frame numbers are capture record numbers.
"""

from __future__ import annotations

import heapq
from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from typing import Protocol

from mavscope.analysis.commanders import COMMANDING, CommandSources, Fields, Link, target_of
from mavscope.analysis.control import ControlSources
from mavscope.analysis.crcextra import Group, Mismatches
from mavscope.analysis.framelist import MAX_FRAMES
from mavscope.analysis.framelist import frame_numbers as _frames
from mavscope.analysis.gnss import GnssAnomalies
from mavscope.analysis.replays import COPIES_KEPT as COPIES_KEPT  # (named here for the tests)
from mavscope.analysis.replays import ReplayedCommands
from mavscope.analysis.sequence import GAP_MIN, SeqChannels, SeqTracker, totals
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus, Frame, decode_payload
from mavscope.notes import Finding, FrameNumbers, GivenUp, finding, sort_findings
from mavscope.transport.base import TRANSPORT_TLOG

BURST_MIN = 3  # bad-CRC frames...
BURST_WINDOW_S = 1.0  # ...each within this long of the previous one make a burst
MAX_BURSTS = 1024  # bursts listed: past it the smallest goes (the newest of those), said as `capacity`
# Messages a ground station may number on a counter of their own, apart from its other messages: both real
# GCS tlogs we hold show it (QGroundControl with ArduSub; Mission Planner through MAVProxy with ArduPlane):
# REQUEST_DATA_STREAM numbered 1..7, one per stream, burst after burst. Commanding messages never qualify:
# a second counter there is another sender until shown otherwise.
OWN_COUNTER = frozenset({"REQUEST_DATA_STREAM"})
OWN_COUNTER_MIN = 3  # frames stepping back before a message's own counter is named
WHICH_SHOWN = 3  # messages named in a sequence finding
# (sender, event, message) counts kept in all for the sequence findings' names: a capture can name a new
# message (an unknown id) in every frame.
MAX_NAMED = 1 << 18

def _link(f: Frame) -> str:
    return f"{f.sysid}/{f.compid}"


class _Run:
    """A run of bad-CRC frames close together, as it accumulates (frame numbers with the group each fits)."""

    __slots__ = ("count", "nums", "first", "last", "links", "serial")

    def __init__(self, serial: int = 0) -> None:
        self.serial = serial  # its number among the runs begun (Mismatches.joined counts frames per run)
        self.count = 0
        self.nums: list[tuple[int, Group | None]] = []  # the first MAX_FRAMES (record, group it fits)
        self.first: float | None = None
        self.last: float | None = None
        self.links: Counter[str] = Counter()


class BadCrcBursts:
    """Runs of bad-CRC frames close together: interference, a failing link, or injection attempts; and the
    bad-CRC frames another definition of their message explains (`dialect-mismatch`, crcextra.Mismatches),
    which are not noise: a frame of a group that is a mismatch so far joins no run, and the few frames
    of a group that came before it was one are taken out of the runs at the end. MAX_BURSTS bursts are
    listed: past it the smallest goes (of equals the newest), said as a `capacity` finding."""

    clean: frozenset[str | int] = frozenset()  # bad-CRC frames only (see Detector)
    notes: frozenset[str] = frozenset({"bad-crc"})
    dialect: Dialect | None = None  # the loaded dialect, to name the definitions (Expert.findings sets it)

    def __init__(self) -> None:
        self.runs: list[tuple[int, int, _Run]] = []  # a heap of (frames, -serial, run): the first to go on top
        self.run = _Run()
        self.mismatches = Mismatches()
        self.given_up = GivenUp(f"bad-CRC bursts (the {MAX_BURSTS:,} largest listed)", "frames")

    def _close(self) -> None:
        run = self.run
        if run.count >= BURST_MIN:  # past MAX_BURSTS the smallest goes, the newest of equals: a flood of small
            # bursts churns its own, a larger or earlier burst stays
            if len(self.runs) < MAX_BURSTS:
                heapq.heappush(self.runs, (run.count, -run.serial, run))
            else:
                g = heapq.heappushpop(self.runs, (run.count, -run.serial, run))[2]
                self.given_up.add(f"a burst of {g.count:,} bad-CRC frames from frame {g.nums[0][0]} not listed "
                                  "(no larger than any listed)", g.count, g.nums[0][0])
        self.run = _Run(run.serial + 1)

    def add(self, f: Frame, fields: Fields | None) -> None:
        if f.crc_status is not CrcStatus.BAD:
            return
        group, mismatch = self.mismatches.add(f)
        if mismatch:
            return
        run, t = self.run, f.time
        if run.count and not (t is not None and run.last is not None and t - run.last <= BURST_WINDOW_S):
            self._close()
            run = self.run
        if not run.count:
            run.first = t
        run.count += 1
        if len(run.nums) < MAX_FRAMES and (not run.nums or run.nums[-1][0] != f.record):
            run.nums.append((f.record, group))
        run.last = t
        run.links[_link(f)] += 1
        if group is not None:
            self.mismatches.joined(group, run.serial)

    def findings(self) -> list[Finding]:
        self._close()
        groups = self.mismatches.groups()
        taken: dict[int, list[tuple[Group, int]]] = {}  # run serial -> (mismatch group, its frames in the run)
        for g in groups:
            for serial, n in self.mismatches.runs.get(g, {}).items():
                taken.setdefault(serial, []).append((g, n))
        gave_up = self.given_up.finding()
        out = [gave_up] if gave_up is not None else []
        for run in sorted((r for _, _, r in self.runs), key=lambda r: r.serial):
            links = Counter(run.links)
            count = run.count
            for g, n in taken.get(run.serial, ()):
                count -= n
                links[f"{g[0]}/{g[1]}"] -= n
            if count < BURST_MIN:
                continue
            span = (run.last - run.first) if run.first is not None and run.last is not None else None
            when = f" within {span:.3f} s" if span is not None else ""
            shown = sorted(lk for lk, n in links.items() if n > 0)
            out.append(finding("bad-crc-burst", f"{count} frames with a bad CRC{when} (links {', '.join(shown)})",
                               [r for r, g in run.nums if g not in groups]))
        return out + self.mismatches.findings(self.dialect)


class SequenceAnomalies:
    """Per link: frames lost for good in large gaps (the same count as the Links table's), duplicates,
    late frames, and many backward steps (two sequence counters under one system/component id). Each
    channel the sender is heard on (source and destination endpoints) has its own counter, as MAVLink
    keeps one per channel: a ground station talking to two vehicles over two links repeats no number.
    The findings name the messages of the frames they list. Where every frame of a link that steps back
    is a message of OWN_COUNTER, that message has a counter of its own: one `seq-own-counter` note says
    so instead of duplicates, late frames and two counters."""

    def __init__(self) -> None:
        self.seqs = SeqChannels()
        self.logged_in_part: frozenset[Link] = frozenset()  # senders a tlog logs in part (Expert.findings sets it)
        self.counts: Counter[Link] = Counter()
        self.events: dict[tuple[Link, str], FrameNumbers] = {}
        self.messages: dict[tuple[Link, str], Counter[str]] = {}  # the messages of each event's frames
        self.named = 0  # their entries in all
        self.cut: set[tuple[Link, str]] = set()  # events whose later messages are not named (MAX_NAMED)

    def add(self, f: Frame, fields: Fields | None) -> None:
        key = (f.sysid, f.compid)
        self.counts[key] += 1
        what, _ = self.seqs.feed(f)
        self.event(key, what, f.record, f.msgname or str(f.msgid))

    def event(self, key: Link, what: str, record: int, message: str) -> None:
        """What sender `key`'s frame in `record` (of `message`) was on its channel (`SeqTracker.feed`), in
        capture order."""
        if what in ("duplicate", "late", "unchanged"):
            ev = self.events.get((key, what))
            if ev is None:
                ev = self.events[(key, what)] = _frames()
                self.messages[(key, what)] = Counter()
            ev.add(record)
            names = self.messages[(key, what)]
            if message in names:
                names[message] += 1
            elif self.named < MAX_NAMED:
                self.named += 1
                names[message] = 1
            else:
                self.cut.add((key, what))

    def _back(self, key: Link) -> tuple[list[int], Counter[str], bool]:
        """The frames of sender `key` listed as duplicates or late (the first MAX_FRAMES), their messages,
        and whether some of those are not named (MAX_NAMED)."""
        nums: list[int] = []
        messages: Counter[str] = Counter()
        for what in ("duplicate", "late"):
            ev = self.events.get((key, what))
            if ev is not None:
                nums += ev.nums
                messages += self.messages.get((key, what), Counter())
        return sorted(nums)[:MAX_FRAMES], messages, (key, "duplicate") in self.cut or (key, "late") in self.cut

    def _own_counter(self, key: Link) -> str | None:
        """The message numbered on a counter of its own by sender `key`: every frame of it that steps back
        (OWN_COUNTER_MIN or more) is that message, one of OWN_COUNTER."""
        seq = self.seqs.totals(key)
        _, messages, cut = self._back(key)
        if cut or len(messages) != 1 or seq.reordered + seq.duplicates - seq.repeats < OWN_COUNTER_MIN:
            return None
        (message,) = messages
        return message if message in OWN_COUNTER else None

    def findings(self) -> list[Finding]:
        out: list[Finding] = []
        for (sysid, compid), chans in self.seqs.senders.items():
            trackers = list(chans.values())
            shared = [tr for tr in trackers if tr.counter_shared]
            if shared:
                out.append(_shared_counter((sysid, compid), shared, totals(trackers).lost))
            if (sysid, compid) in self.logged_in_part:  # said in place of seq-gap: not link loss
                if lost := totals(trackers).lost:
                    out.append(logged_in_part((sysid, compid), lost, trackers))
                continue
            gaps = [(tr.missed_in(g), g) for tr in trackers for g in tr.gaps if tr.missed_in(g) >= GAP_MIN]
            if not gaps:
                continue
            large = sum(tr.large_gaps for tr in trackers)
            kept = sum(len(tr.gaps) for tr in trackers)
            size, largest = max(gaps, key=lambda mg: mg[0])
            more = f" (and {large - kept} more not listed)" if large > kept else ""
            out.append(finding("seq-gap",
                               f"link {sysid}/{compid}: {sum(m for m, _ in gaps)} frames lost in "
                               f"{len(gaps)} gap(s) of {GAP_MIN} or more{more}, the largest {size} "
                               f"(seq {largest.before} -> {largest.after}); {totals(trackers).lost} lost in all, "
                               "as in the Links table", sorted(g.record for _, g in gaps)))
        own = {key: m for key in self.counts if (m := self._own_counter(key)) is not None}
        for key, message in own.items():
            seq = self.seqs.totals(key)
            nums, _, _ = self._back(key)
            out.append(finding("seq-own-counter",
                               f"link {key[0]}/{key[1]}: {seq.duplicates + seq.reordered} frames out of sequence, "
                               f"all {message} ({seq.duplicates} repeat a number already seen, {seq.reordered} fill "
                               f"a gap): {message} numbered on a counter of its own, as ground stations do "
                               "(QGroundControl, Mission Planner/MAVProxy tlogs); not frames lost, late or from "
                               "another sender", nums))
        for (key, what), ev in self.events.items():
            sysid, compid = key
            seq = self.seqs.totals(key)
            which = _which(self.messages.get((key, what), Counter()), (key, what) in self.cut)
            if what == "duplicate" and seq.duplicates and key not in own:
                out.append(finding("seq-duplicate", f"link {sysid}/{compid}: {seq.duplicates} frames repeat a "
                                                    f"sequence number already seen on their channel{which}",
                                   ev.nums))
            elif what == "unchanged":
                out.append(finding("seq-unchanged", unchanged_message(key, ev.count), ev.nums))
            elif what == "late" and key not in own:
                out.append(finding("seq-reordered", f"link {sysid}/{compid}: {ev.count} frames came after later "
                                                    f"ones in sequence, filling a gap{which}", ev.nums))
        for key, total in self.counts.items():
            seq = self.seqs.totals(key)
            back = seq.reordered + seq.duplicates - seq.repeats  # steps back (not the same number again)
            if back >= 5 and back * 20 >= total and key not in own:
                nums, messages, cut = self._back(key)
                out.append(finding("seq-interleaved",
                                   f"link {key[0]}/{key[1]}: {back} of {total} frames step back in sequence: two "
                                   "sequence counters under one system/component id on one channel (two senders, "
                                   "or one sender's two MAVLink channels where the capture cannot tell them apart, "
                                   f"as in a tlog){_which(messages, cut)}", nums))
        return out


def logged_in_part(key: Link, lost: int, trackers: list[SeqTracker]) -> Finding:
    """`seq-logged-in-part`: ground station `key`'s frames in a tlog miss `lost` numbers (as the Links table
    counts them), which the tlog did not log: not link loss. The frames: those after its large gaps."""
    large = sorted(g.record for tr in trackers for g in tr.gaps)[:MAX_FRAMES]
    return finding("seq-logged-in-part",
                   f"link {key[0]}/{key[1]}: {lost} numbers missing from its sequence, as in the Links table: a "
                   "ground station (HEARTBEAT type GCS) in a tlog; a tlog records what the ground station received, "
                   "its own frames are logged only in part: this is not link loss", large)


def _shared_counter(key: Link, trackers: list[SeqTracker], lost: int) -> Finding:
    """`seq-shared-counter`: sender `key` numbers its frames on one counter with other ids on its channel
    (`trackers`: its channels where it does, SeqTracker.counter_shared). The frames: each channel's first jump
    over numbers all used by another id."""
    partners = sorted({tr.partner for tr in trackers if tr.partner >= 0})
    named = ", ".join(f"{p >> 8}/{p & 0xFF}" for p in partners)
    skipped = sum(tr.shared for tr in trackers)
    full = sum(tr.full_steps for tr in trackers)
    jumps = sum(tr.gap_steps for tr in trackers)
    return finding("seq-shared-counter",
                   f"link {key[0]}/{key[1]}: {full} of its {jumps} jumps in sequence skip only numbers another id "
                   f"on its channel used ({named} first): one counter numbers the frames of several ids, as one "
                   f"program sending as several does (BlueOS's mavlink-server, a companion computer); the "
                   f"{skipped} numbers the others used are not frames lost ({lost} lost in all, as in the Links "
                   "table)", sorted(tr.first_full for tr in trackers))


def _which(messages: Counter[str], cut: bool = False) -> str:
    """` (all M)`, or ` (M1, M2, M3 and k more)` most frequent first: the messages of a finding's frames
    (`cut`: more were not named, MAX_NAMED: "and more"). Named, not counted: a restarted counter's first
    frames are listed with the duplicates they seemed until the restart showed (SeqTracker), so counts here
    would not add up to the finding's."""
    top = [m for m, _ in sorted(messages.items(), key=lambda mc: (-mc[1], mc[0]))]
    if cut:
        return f" ({', '.join(top[:WHICH_SHOWN])} and more)" if top else " (messages not named: too many)"
    if not messages:
        return ""
    if len(messages) == 1:
        (m, n), = messages.items()
        return f" (all {m})" if n > 1 else f" ({m})"
    more = f" and {len(top) - WHICH_SHOWN} more" if len(top) > WHICH_SHOWN else ""
    return f" ({', '.join(top[:WHICH_SHOWN])}{more})"


def unchanged_message(sender: Link, count: int) -> str:
    """The `seq-unchanged` finding's words: what was seen, and one known cause among others."""
    return (f"link {sender[0]}/{sender[1]}: {count} frame(s) repeat the sequence number of the frame before "
            "them from the same sender with other contents (neither copies nor losses; one known cause: MAVProxy "
            "writes the parameters it fetched over FTP into its tlog under one number)")


class UnsignedCommands:
    """Unsigned commanding frames where the sender or its target signs: a downgrade. Signing senders are
    known only once their signed frames are seen, so candidates wait for the end (bounded: MAX_FRAMES
    listed, all counted per sender)."""

    clean: frozenset[str | int] = COMMANDING  # and which systems sign: `signers`, where frames are counted in bulk
    notes: frozenset[str] = frozenset()  # (a frame whose note is a code is unsigned: `add` reads its commands)

    def __init__(self) -> None:
        self.signing: set[int] = set()
        self.candidates: dict[tuple[int, int, int], FrameNumbers] = {}  # (sysid, compid, target) -> frames
        self.names: dict[tuple[int, int, int], Counter[str]] = {}

    def signers(self, sysids: Iterable[int]) -> None:
        """Systems seen sending signed frames (as `add` notes them from their signed frames)."""
        self.signing.update(sysids)

    def add(self, f: Frame, fields: Fields | None) -> None:
        if f.signature is not None:
            self.signing.add(f.sysid)
            return
        md = f.msgdef
        if fields is None or md is None or md.name not in COMMANDING:
            return
        target = target_of(fields)
        key = (f.sysid, f.compid, target if isinstance(target, int) else -1)
        if key not in self.candidates:
            self.candidates[key] = _frames()
            self.names[key] = Counter()
        self.candidates[key].add(f.record)
        self.names[key][md.name] += 1

    def findings(self) -> list[Finding]:
        out = []
        for (sysid, compid, target), frames in self.candidates.items():
            if sysid in self.signing or target in self.signing:
                kinds = ", ".join(f"{n} {c}" for n, c in self.names[(sysid, compid, target)].most_common())
                out.append(finding("unsigned-command", f"{frames.count} unsigned commanding frame(s) from "
                                                       f"{sysid}/{compid} to system {target}, where signed traffic "
                                                       f"is seen ({kinds})", frames.nums))
        return out


class KeyLeaks:
    """SETUP_SIGNING carries the secret key in clear: whoever holds the capture holds the key."""

    clean: frozenset[str | int] = frozenset({"SETUP_SIGNING"})
    notes: frozenset[str] = frozenset()

    def __init__(self) -> None:
        self.frames = _frames()

    def add(self, f: Frame, fields: Fields | None) -> None:
        if f.msgdef is not None and f.msgdef.name == "SETUP_SIGNING":
            self.frames.add(f.record)

    def findings(self) -> list[Finding]:
        if not self.frames.count:
            return []
        return [finding("key-leak", f"{self.frames.count} SETUP_SIGNING frame(s): the signing key travels in "
                                    "clear in this capture", self.frames.nums)]


class HiddenFrames:
    """Frames MAVLink's C library reads where the framer shows other bytes (mavscope.mavlink.hidden): the
    framer's `hidden-frame` notes, summed up with what the frames are."""

    clean: frozenset[str | int] = frozenset()  # a clean frame carries no note
    notes: frozenset[str] = frozenset({"hidden-frame"})

    def __init__(self) -> None:
        self.frames = _frames()
        self.what: Counter[str] = Counter()

    def add(self, f: Frame, fields: Fields | None) -> None:
        if any(n.code == "hidden-frame" for n in f.notes):
            self.frames.add(f.record)
            self.what[f"{f.msgname or f'message {f.msgid}'} from {_link(f)}"] += 1

    def findings(self) -> list[Finding]:
        if not self.frames.count:
            return []
        what = ", ".join(f"{n} {w}" for w, n in sorted(self.what.items(), key=lambda kv: (-kv[1], kv[0]))[:5])
        more = " ..." if len(self.what) > 5 else ""
        return [finding("hidden-frame", f"{self.frames.count} frame(s) that MAVLink's C library (ArduPilot, PX4, "
                                        f"QGroundControl) reads inside bytes the framer shows as other frames or "
                                        f"skipped: {what}{more}", self.frames.nums)]


class Detector(Protocol):
    """`add` gets the decoded payload of commanding frames and HEARTBEATs, and of the messages named in the
    detector's `wants` attribute where it has one.

    A detector may say in a `clean` attribute which clean frames (good CRC, no note, plaintext, no verdict
    but `no-key`) can change what it finds: the names (or ids) of their messages. A caller that knows
    which frames are clean (the export's native source) then gives it only those of them, and every
    other frame. Without the attribute it gets every frame. With `clean`, it may also say in `notes` which
    notes it reads on frames of other messages: a caller that knows a frame's notes are only some it
    can tell without a Frame (FrameBatch.coded: bad-crc, unsigned-in-signed-stream, v1-in-signed-stream)
    gives it such a frame of another message only when it has one of those."""

    def add(self, f: Frame, fields: Fields | None) -> None: ...

    def findings(self) -> list[Finding]: ...


# Factories: each is called with no argument, or with the dialect when it is in DIALECT_DETECTORS.
DETECTORS: list[Callable[..., Detector]] = [BadCrcBursts, SequenceAnomalies, CommandSources, ReplayedCommands,
                                            UnsignedCommands, KeyLeaks, ControlSources, GnssAnomalies, HiddenFrames]
DIALECT_DETECTORS: frozenset[Callable[..., Detector]] = frozenset({ControlSources, GnssAnomalies})
# The detectors Expert.logged_in_part reads: an Expert of only these gives that verdict (the TUI's statistics)
LOGGED_IN_PART_DETECTORS: tuple[Callable[..., Detector], ...] = (SequenceAnomalies, CommandSources)


class Expert:
    """Every detector in one pass: `add(frame)` per frame in capture order, then `findings()`."""

    def __init__(self, dialect: Dialect, detectors: Sequence[Callable[..., Detector]] | None = None) -> None:
        self.dialect = dialect
        self.detectors = [d(dialect) if d in DIALECT_DETECTORS else d()
                          for d in (DETECTORS if detectors is None else detectors)]
        self.decode = COMMANDING.union({"HEARTBEAT"}, *(getattr(d, "wants", ()) for d in self.detectors))
        self.recorded = False  # frames from a tlog, a ground station's recording (expert_batch sets it too)
        self.seqs = SeqChannels()  # the sequence counters batches are fed to (expert_batch.feed) without steps

    def add(self, f: Frame) -> Fields | None:
        """Frame `f` to every detector; the fields decoded for them (`fields`), for a caller that wants them."""
        if f.transport == TRANSPORT_TLOG:
            self.recorded = True
        fields = self.fields(f)
        for d in self.detectors:
            d.add(f, fields)
        return fields

    def fields(self, f: Frame) -> Fields | None:
        """The decoded payload the detectors get with `f`: of the messages they decode, CRC not bad."""
        md = f.msgdef
        if md is not None and md.name in self.decode and f.crc_status is not CrcStatus.BAD:
            return decode_payload(f)
        return None

    def logged_in_part(self) -> frozenset[Link]:
        """The senders whose own frames the capture logs only in part: in a tlog (`recorded`), every
        component of a system that sent a HEARTBEAT of type GCS (CommandSources.gcs). A tlog holds what the
        ground station that wrote it received, and its own frames (and those it forwards) only in part: the
        numbers missing from their sequence are not link loss (`seq-logged-in-part`, stats' Links table)."""
        seq = next((d for d in self.detectors if isinstance(d, SequenceAnomalies)), None)
        cs = next((d for d in self.detectors if isinstance(d, CommandSources)), None)
        if not self.recorded or seq is None or cs is None:
            return frozenset()
        return frozenset(s for s in seq.seqs.senders if s[0] in cs.gcs)

    def findings(self) -> list[Finding]:
        out: list[Finding] = []
        part = self.logged_in_part()
        for d in self.detectors:
            if isinstance(d, SequenceAnomalies):
                d.logged_in_part = part
            if isinstance(d, BadCrcBursts):  # (made without the dialect: DETECTORS' factories take none)
                d.dialect = self.dialect
            out.extend(d.findings())
        return sort_findings(out)


def expert_findings(frames: Iterable[Frame], dialect: Dialect,
                    detectors: Sequence[Callable[..., Detector]] | None = None) -> list[Finding]:
    """Every detector's findings over `frames`, most severe first."""
    expert = Expert(dialect, detectors)
    for f in frames:
        expert.add(f)
    return expert.findings()
