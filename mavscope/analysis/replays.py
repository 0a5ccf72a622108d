"""The expert's ReplayedCommands detector: commands and setpoints repeated byte for byte out of place.

A replay is a frame sent again as it was recorded: the same bytes, sequence number (and for a signed frame,
signature timestamp) included. Identical bytes alone do not make one: a periodic stream repeats its neutral
value byte for byte each time the sender's 8-bit counter comes round. What tells a replay is its place: out
of the sender's sequence, or a signature timestamp that did not advance (docs/analysis.md, "Replays").
"""

from __future__ import annotations

from collections import Counter

from mavscope.analysis.commanders import COMMANDING, Fields, Link
from mavscope.analysis.framelist import MAX_FRAMES
from mavscope.analysis.framelist import frame_numbers as _frames
from mavscope.analysis.sequence import SeqChannels
from mavscope.mavlink.frame import CrcStatus, Frame, SignatureStatus
from mavscope.notes import Finding, FrameNumbers, GivenUp, finding, pop_newest

COPIES_KEPT = 65_536  # commanding frames remembered for replay detection (past it the newest but the new one goes)
LISTED = MAX_FRAMES // 2  # copies of a run held with their frames; beyond, counted by message
IN_PLACE = frozenset({"first", "next", "late", "reset"})  # a copy with this step is where its sender's counter is
PASSED = frozenset({"next", "gap", "reset"})  # the counter moved past the number a copy ahead of it took


class _Held:
    """Copies of one channel whose place in the sender's sequence the frames after them tell: a run ahead
    of the counter (a jump forward, and the copies that follow it number by number: later frames say
    whether the counter ran on past them), and those behind it (the counter ran on from before them, or it
    restarted). The copies of each are judged together: the first LISTED with their frames (a finding lists
    MAX_FRAMES frame numbers, two a copy: those after them would not be listed), the others counted per
    message, with the order of the first (so nothing is given up and memory stays bounded)."""

    __slots__ = ("ahead", "ahead_seq", "ahead_more", "behind", "behind_more")

    def __init__(self) -> None:
        self.ahead: list[tuple[int, int, str]] = []  # (original, copy, message), at most LISTED
        self.ahead_seq = 0  # the number of the run's first copy
        self.ahead_more: dict[str, list[int]] = {}  # message -> [copies past LISTED, order unused]
        self.behind: list[tuple[int, int, int, str]] = []  # (order held, original, copy, message), at most LISTED
        self.behind_more: dict[str, list[int]] = {}  # message -> [copies past LISTED, order of the first]


class ReplayedCommands:
    """Frames of commands and of setpoint streams (COMMANDING) repeated byte for byte out of place in their
    sender's sequence, aggregated per link; and frames the security layer judged signature replays.

    A copy (the bytes of a remembered frame of the same message: the same sequence number and payload)
    is judged by its place on its channel's counter (SeqChannels, as the Links table follows it), with the
    frames after it: a periodic stream repeats its neutral value byte for byte each time the 8-bit counter
    comes round (a neutral-stick MANUAL_CONTROL every 256 frames), and such a copy is in its place.
    - In place: the sender's next number, a number that fills a gap (a late frame), a restarted counter.
    - Behind the counter (a number already used, filling nothing): a replay when the sender's counter then
      runs on from before it (the next frame steps forward from the number before the copy); in place when
      the counter turns out to have restarted (a reboot, or a dropout of 128 frames or more that the 8-bit
      counter cannot show: RESET_RUN frames in a row); at the end of the capture, a replay.
    - Ahead of the counter (a jump forward, with the copies that follow it number by number: a recorded run
      sent again): a replay when the run's first number comes again before the counter moves past the run
      (the sender's own frames fill the jump and reach it), in place when the counter moves on.
    - A signed copy is a replay wherever it is: its signature timestamp did not advance.
    Bounds (docs/security.md, "Bounds"): COPIES_KEPT frames remembered; past it the newest remembered but the
    one just seen is forgotten (a flood of distinct frames churns its own, the commands seen before it stay),
    said as a `capacity` finding. Copies held per channel: every one judged (_Held)."""

    def __init__(self) -> None:
        self.seqs = SeqChannels()
        self.seen: dict[bytes, int] = {}  # raw -> its last record (in the order first seen)
        self.forgotten = GivenUp(f"replay detection's remembered command and setpoint frames (at most "
                                 f"{COPIES_KEPT:,})", "frames")
        self.held: dict[int, tuple[Link, _Held]] = {}  # id(channel tracker) -> its sender and held copies
        self.order = 0  # copies held so far (the order the end of the capture judges them in)
        self.copies: dict[Link, tuple[FrameNumbers, Counter[str]]] = {}
        self.replays: dict[Link, tuple[FrameNumbers, Counter[str]]] = {}

    def add(self, f: Frame, fields: Fields | None) -> None:
        step, _ = self.seqs.feed(f)
        self.judge(f, step, id(self.seqs.tracker(f)))

    def judge(self, f: Frame, step: str, channel: int) -> None:
        """The frame after its channel's tracker took it (`step`); `channel` names the channel."""
        link = (f.sysid, f.compid)
        name = f.msgname or str(f.msgid)
        sec = f.security
        replay = sec is not None and sec.signature_status is SignatureStatus.REPLAY
        md = f.msgdef
        tracked = not replay and md is not None and md.name in COMMANDING and f.crc_status is CrcStatus.OK
        prev = self.seen.get(f.raw) if tracked else None
        entry = self.held.get(channel)
        if entry is not None:
            held = entry[1]
            if held.ahead and prev is not None and step == "next" and f.signature is None:  # the run ahead goes on
                if len(held.ahead) < LISTED:
                    held.ahead.append((prev, f.record, name))
                else:
                    held.ahead_more.setdefault(name, [0, 0])[0] += 1
                self._resolve_behind(link, held, step)
                return
            self._resolve(link, held, f.seq, step)
            if not held.ahead and not held.behind:
                del self.held[channel]
        if replay:
            self._count(self.replays, link, (f.record,), name)
            return
        if not tracked:
            return
        raw = f.raw
        if prev is not None and f.signature is not None:
            self._count(self.copies, link, (prev, f.record), name)  # the signature timestamp did not advance
            return
        if prev is None or step in IN_PLACE:
            self.seen[raw] = f.record
            if len(self.seen) > COPIES_KEPT:
                _, record = pop_newest(self.seen, raw)
                self.forgotten.add(f"the frame of record {record} forgotten for the one of record {f.record}: a "
                                   "later copy of it is not recognised", record=f.record)
            return
        entry = self.held.get(channel)
        if entry is None:
            entry = self.held[channel] = (link, _Held())
        held = entry[1]
        if step == "gap":
            held.ahead, held.ahead_more = [(prev, f.record, name)], {}
            held.ahead_seq = f.seq
            return
        if len(held.behind) < LISTED:
            held.behind.append((self.order, prev, f.record, name))
        else:
            held.behind_more.setdefault(name, [0, self.order])[0] += 1
        self.order += 1

    def _resolve(self, link: Link, held: _Held, seq: int, step: str) -> None:
        """What the frame after them (number `seq`, `step` on the channel) tells of the copies held."""
        if held.ahead:
            if step in PASSED:
                held.ahead, held.ahead_more = [], {}
            elif seq == held.ahead_seq and step in ("duplicate", "unchanged"):
                for orig, copy, name in held.ahead:
                    self._count(self.copies, link, (orig, copy), name)
                for name, (n, _) in held.ahead_more.items():
                    self._count(self.copies, link, (), name, n)
                held.ahead, held.ahead_more = [], {}
        self._resolve_behind(link, held, step)

    def _resolve_behind(self, link: Link, held: _Held, step: str) -> None:
        if held.behind:
            if step in ("next", "gap"):
                for _, orig, copy, name in held.behind:
                    self._count(self.copies, link, (orig, copy), name)
                for name, (n, _) in held.behind_more.items():
                    self._count(self.copies, link, (), name, n)
                held.behind, held.behind_more = [], {}
            elif step == "reset":
                held.behind, held.behind_more = [], {}

    def finish(self) -> None:
        """The end of the capture: copies still behind their counter are replays (in the order they came: those
        counted per message at the first's); one still ahead of it is in place (nothing came to say otherwise)."""
        left: list[tuple[int, Link, tuple[int, ...], str, int]] = []
        for link, held in self.held.values():
            left += [(order, link, (orig, copy), name, 1) for order, orig, copy, name in held.behind]
            left += [(order, link, (), name, n) for name, (n, order) in held.behind_more.items()]
        self.held = {}
        for _, link, records, name, n in sorted(left, key=lambda c: c[0]):
            self._count(self.copies, link, records, name, n)

    @staticmethod
    def _count(table: dict[Link, tuple[FrameNumbers, Counter[str]]], link: Link, records: tuple[int, ...],
               name: str, n: int = 1) -> None:
        """Count `n` frames of message `name` (listing `records`: the copy, and its original if known)."""
        entry = table.get(link)
        if entry is None:
            entry = table[link] = (_frames(), Counter())
        for r in records:
            entry[0].add(r)
        entry[1][name] += n

    def findings(self) -> list[Finding]:
        self.finish()
        out = []
        for (sysid, compid), (frames, names) in self.copies.items():
            kinds = ", ".join(f"{n} {c}" for n, c in names.most_common())
            out.append(finding("replayed-command",
                               f"link {sysid}/{compid}: {sum(names.values())} command or setpoint frame(s) repeat an "
                               f"earlier one byte for byte (sequence number included) out of place in the sender's "
                               f"sequence, or signed with a timestamp that did not advance ({kinds}): replays or "
                               "duplicated packets", frames.nums))
        for (sysid, compid), (frames, names) in self.replays.items():
            kinds = ", ".join(f"{n} {c}" for n, c in names.most_common())
            out.append(finding("replay", f"link {sysid}/{compid}: {frames.count} frame(s) whose signature verifies "
                                         f"with a timestamp not newer than its stream's ({kinds})", frames.nums))
        gave_up = self.forgotten.finding()
        out += [gave_up] if gave_up is not None else []
        return out
