"""Which rows an analysis reports under a display filter.

As in Wireshark's sequence and conversation analyses, every analysis runs over every frame (loss needs
every sequence number, an ACK needs its command); the display filter only selects what is reported:
a stream, link or system with a frame the filter matched, a command or transfer one of whose frames it
matched, a finding about such a frame. `Selection.see(frame)` is called for every frame in capture
order; without a filter everything is selected and nothing is recorded.
"""

from __future__ import annotations

from collections.abc import Iterable

from mavscope.filter import DisplayFilter
from mavscope.mavlink.frame import Frame
from mavscope.mavlink.semantics import message_label


class Selection:
    """The frames a display filter matched, as the keys analyses report by."""

    def __init__(self, flt: DisplayFilter | None = None, *, active: bool | None = None) -> None:
        """`flt`: the display filter `see` applies. Without one, `active=True` makes a selection that
        `mark` fills (the TUI marks the rows of its filtered view)."""
        self.filter = flt
        self._active = flt is not None if active is None else active
        self.matched = 0
        self.records: set[int] = set()  # frame (record) numbers matched
        self.streams: set[tuple[int, int, str]] = set()  # (sysid, compid, message) matched
        self.links: set[tuple[int, int]] = set()
        self.systems: set[int] = set()

    @property
    def active(self) -> bool:
        return self._active

    def see(self, f: Frame) -> bool:
        """Whether the filter matches `f` (always True without one); remembers what it matched."""
        if self.filter is None:
            return True
        if not self.filter.matches(f):
            return False
        self.mark(f)
        return True

    def mark(self, f: Frame) -> None:
        """Count `f` as selected."""
        self.matched += 1
        self.records.add(f.record)
        self.streams.add((f.sysid, f.compid, message_label(f.msgid, f.msgdef)))
        self.links.add((f.sysid, f.compid))
        self.systems.add(f.sysid)

    def any_record(self, records: Iterable[int]) -> bool:
        """Whether one of these frame numbers was matched (always True without a filter)."""
        return not self._active or any(r in self.records for r in records)

    def stream(self, key: tuple[int, int, str]) -> bool:
        return not self._active or key in self.streams

    def link(self, key: tuple[int, int]) -> bool:
        return not self._active or key in self.links

    def system(self, sysid: int) -> bool:
        return not self._active or sysid in self.systems
