"""Bad CRCs that another definition of the message explains: a dialect mismatch, not line noise.

A MAVLink CRC is the X.25 CRC of the frame after its start byte (header and payload), with one more byte
accumulated: the message's CRC_EXTRA, a hash of its name and fields. A sender whose dialect defines a
message id otherwise (another name, another field, another type) computes its CRCs with another
CRC_EXTRA, and every one of its frames of that id fails the receiver's check. Given the CRC of the
header and payload, the X.25 step is invertible: exactly one byte accumulated last gives the frame's CRC
(`fitting_extra`, O(1)). A damaged frame fits a random byte 1 time in 256; the frames of one sender and
id that all fit one other CRC_EXTRA are that sender's definition of the id (`dialect-mismatch`, with the
definitions of pymavlink's dialects and of the loaded dialect that have it), not noise.

Bounded (docs/security.md, "Bounds"): MAX_GROUPS groups are followed. Crafted bad-CRC frames can each fit a
new group; past the bound the newest group of one frame goes for the new one (a flood churns its own), a
group of two frames or more is never given up (when every group has two, the new frame's group is), and
each give-up is said as a `capacity` finding.
"""

from __future__ import annotations

from collections import Counter
from functools import cache

from fastcrc import crc16

from mavscope.analysis.framelist import frame_numbers
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus, Frame
from mavscope.notes import Finding, FrameNumbers, GivenUp, finding, pop_newest
from mavscope.wire import HEADER_V1, HEADER_V2, STX_V2

MISMATCH_MIN = 5  # frames of one sender and id fitting one other CRC_EXTRA that make a dialect mismatch
NAMES_SHOWN = 4  # definitions named in a finding
MAX_GROUPS = 4096  # (sender, id, CRC_EXTRA that fits) groups followed (past it: the newest of one frame goes)
Group = tuple[int, int, int, int]  # (sysid, compid, msgid, the CRC_EXTRA that fits)


def _step(tmp: int) -> int:
    return ((tmp << 8) ^ (tmp << 3) ^ (tmp >> 4)) & 0xFFFF


# X.25 accumulates byte b into crc as: t = b ^ (crc & 0xFF); t ^= (t << 4) & 0xFF;
# crc' = (crc >> 8) ^ (t << 8) ^ (t << 3) ^ (t >> 4). The last three terms take 256 distinct values of t.
_UNSTEP = {_step(t): t for t in range(256)}


def fitting_extra(raw: bytes, version: int, length: int, crc: int) -> int | None:
    """The CRC_EXTRA byte that makes frame `raw`'s CRC `crc` (over its header and `length` payload bytes), or
    None when no byte does (a damaged frame, 255 times in 256)."""
    hlen = HEADER_V2 if version == 2 else HEADER_V1
    base = crc16.mcrf4xx(raw[1:hlen + length])
    t = _UNSTEP.get(crc ^ (base >> 8))
    if t is None:
        return None
    t1 = t ^ ((t & 0x0F) << 4)  # undo t ^= (t << 4) & 0xFF: the low nibble is unchanged
    return t1 ^ (base & 0xFF)


def fit_of(f: Frame) -> Group | None:
    """The group of a bad-CRC frame whose CRC another CRC_EXTRA explains, else None."""
    if f.crc_status is not CrcStatus.BAD or f.crc is None or f.msgdef is None or len(f.raw) < 3:
        return None
    if (f.raw[0] == STX_V2) != (f.version == 2):
        return None
    extra = fitting_extra(f.raw, f.version, f.length, f.crc)
    return None if extra is None else (f.sysid, f.compid, f.msgid, extra)


@cache
def _pymavlink_definitions() -> tuple[tuple[str, int, str, int], ...]:
    """(dialect, message id, name, CRC_EXTRA) of every message of pymavlink's generated MAVLink 2 dialects
    (read only when a mismatch is found)."""
    import importlib
    import pkgutil

    import pymavlink.dialects.v20 as package

    out = []
    for info in sorted(pkgutil.iter_modules(package.__path__), key=lambda i: i.name):
        if info.name in ("all", "python_array_test", "test"):
            continue
        try:
            module = importlib.import_module(f"{package.__name__}.{info.name}")
        except Exception:  # noqa: BLE001 - a dialect module that does not import names nothing
            continue
        for mid, cls in getattr(module, "mavlink_map", {}).items():
            out.append((info.name, int(mid), str(cls.msgname), int(cls.crc_extra)))
    return tuple(out)


def definitions(msgid: int, extra: int, dialect: Dialect | None) -> list[str]:
    """The definitions known with CRC_EXTRA `extra`: message `msgid` of a pymavlink dialect first, then
    any message of the loaded dialect or of pymavlink's (another id: the sender's dialect may number it
    otherwise). Text such as "TIMESYNC (id 111, common.xml)"."""
    same: list[tuple[str, int, str]] = []
    other: list[tuple[str, int, str]] = []
    for name, mid, msg, crc in _pymavlink_definitions():
        if crc == extra:
            (same if mid == msgid else other).append((msg, mid, f"{name}.xml"))
    if dialect is not None:
        for md in dialect.messages.values():
            if md.crc_extra == extra:
                (same if md.id == msgid else other).append((md.name, md.id, md.source))
    seen: set[tuple[str, int]] = set()
    out = []
    for msg, mid, where in same + other:
        if (msg, mid) not in seen:
            seen.add((msg, mid))
            out.append(f"{msg} (id {mid}, {where})")
    return out


class Mismatches:
    """Bad-CRC frames per (sender, id, CRC_EXTRA that fits): `add` returns the frame's group and whether that
    group is a mismatch so far (MISMATCH_MIN frames or more); `joined` says which run of bad CRCs a frame of a
    group not yet a mismatch joined (BadCrcBursts takes them out of the run if it becomes one); `findings`
    at the end. At most MAX_GROUPS groups (see the module's doc)."""

    def __init__(self) -> None:
        self.fits: dict[Group, FrameNumbers] = {}
        self.single: dict[Group, None] = {}  # the groups of one frame, in the order they came
        self.runs: dict[Group, Counter[int]] = {}  # a group's frames per run (BadCrcBursts' serial) they joined
        self.expected: dict[int, tuple[str, int]] = {}  # msgid -> (name, CRC_EXTRA) of the loaded dialect
        self.given_up = GivenUp(f"dialect-mismatch groups of bad-CRC frames (at most {MAX_GROUPS:,} (sender, id, "
                                "CRC_EXTRA that fits) followed)", "frames")

    def add(self, f: Frame) -> tuple[Group | None, bool]:
        g = fit_of(f)
        if g is None:
            return None, False
        fn = self.fits.get(g)
        if fn is None:
            if len(self.fits) >= MAX_GROUPS and not self._room(g, f.record):
                return None, False
            fn = self.fits[g] = frame_numbers()
            self.single[g] = None
            md = f.msgdef
            if md is not None:
                self.expected.setdefault(f.msgid, (md.name, md.crc_extra))
        elif fn.count == 1:
            del self.single[g]
        fn.add(f.record)
        return g, fn.count >= MISMATCH_MIN

    def _room(self, g: Group, record: int) -> bool:
        """Room for group `g`, new at `record`, in a full table: the newest group of one frame given up (said),
        or none of one frame, `g` given up (False)."""
        if not self.single:
            self.given_up.add(f"the frame of {_group_text(g)} not followed (every group followed has 2 frames "
                              "or more)", record=record)
            return False
        old, _ = pop_newest(self.single, g)
        del self.fits[old]
        self.runs.pop(old, None)
        self.given_up.add(f"the group of {_group_text(old)} (1 frame) given up for a new one", record=record)
        return True

    def joined(self, g: Group, run: int) -> None:
        """A frame of group `g` (not yet a mismatch) joined run `run` of bad CRCs."""
        if g in self.fits:
            self.runs.setdefault(g, Counter())[run] += 1

    def groups(self) -> set[Group]:
        """The groups that are mismatches."""
        return {g for g, fn in self.fits.items() if fn.count >= MISMATCH_MIN}

    def findings(self, dialect: Dialect | None) -> list[Finding]:
        gave_up = self.given_up.finding()
        out = [gave_up] if gave_up is not None else []
        for g in sorted(self.groups()):
            sysid, compid, msgid, extra = g
            fn = self.fits[g]
            name, ours = self.expected.get(msgid, (str(msgid), -1))
            known = definitions(msgid, extra, dialect)
            named = (f"; CRC_EXTRA {extra} is that of {', '.join(known[:NAMES_SHOWN])}"
                     + (f" and {len(known) - NAMES_SHOWN} more" if len(known) > NAMES_SHOWN else "")
                     if known else f"; no definition known to mavscope has CRC_EXTRA {extra}")
            out.append(finding("dialect-mismatch",
                               f"{fn.count} frame(s) of message id {msgid} from {sysid}/{compid} fail the CRC with "
                               f"CRC_EXTRA {ours} ({name} in the dialect loaded) and every one fits CRC_EXTRA "
                               f"{extra}: the sender defines message {msgid} otherwise (another dialect or version "
                               f"of it), not line noise{named}; load its dialect (--dialect)", fn.nums))
        return out


def _group_text(g: Group) -> str:
    return f"message id {g[2]} from {g[0]}/{g[1]} fitting CRC_EXTRA {g[3]}"
