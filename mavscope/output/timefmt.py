"""The time column of summary lines (`read -t FORMAT`) and the `frame.time*` fields of `-T fields`, as tshark.

tshark's `-t` formats: `r` relative to the first record (the default), `a` the absolute time of day, `ad`
with the date (YYYY-MM-DD), `adoy` with the year and day of the year (YYYY/DOY), `u`, `ud`, `udoy` the same
in UTC (`a*` in the local time zone, as tshark: TZ sets it), `e` seconds since the epoch, `d` since the
previous captured record, `dd` since the previous shown frame (after `-Y`). Six decimals, as tshark shows a
pcap's microseconds. A frame whose record has no time shows `-`.

`Clock` follows a run: `captured(number, time)` for every capture record (`d`; Session.record_hooks), `text(frame)` for
each frame shown (a summary line), or `field` for each time field of a record's line and then `show`. Its
`field(name, frame)` gives `frame.time` (tshark's absolute text, `Mar 14, 2026 10:00:00.000812000 UTC`),
`frame.time_epoch`, `frame.time_relative`, `frame.time_delta` and `frame.time_delta_displayed`, as `-T
fields -e` prints them (nine decimals, as tshark's).
"""

from __future__ import annotations

from datetime import datetime, timezone
from typing import Final

from mavscope.errors import UsageError
from mavscope.mavlink.frame import Frame

FORMATS: Final = ("a", "ad", "adoy", "d", "dd", "e", "r", "u", "ud", "udoy")
TIME_FIELDS: Final = frozenset({"frame.time", "frame.time_epoch", "frame.time_relative", "frame.time_delta",
                                "frame.time_delta_displayed"})
# the wall-clock formats: strftime layout, and whether in UTC
_KEPT: Final = 1 << 16  # record times kept for `d`
_WALL: Final = {"a": ("%H:%M:%S", False), "ad": ("%Y-%m-%d %H:%M:%S", False), "adoy": ("%Y/%j %H:%M:%S", False),
                "u": ("%H:%M:%S", True), "ud": ("%Y-%m-%d %H:%M:%S", True), "udoy": ("%Y/%j %H:%M:%S", True)}


def check_format(fmt: str) -> str:
    if fmt not in FORMATS:
        raise UsageError(f"-t {fmt}: one of {', '.join(FORMATS)} (as tshark's -t)")
    return fmt


def _wall(t: float, fmt: str) -> str:
    """Time of day (with the date `fmt` asks for, in UTC or local time) of Unix time `t`, to the microsecond."""
    layout, utc = _WALL[fmt]
    try:
        when = datetime.fromtimestamp(t, timezone.utc) if utc else datetime.fromtimestamp(t).astimezone()
    except (OverflowError, OSError, ValueError):  # a time no calendar holds: its seconds
        return f"{t:.6f}"
    return f"{when.strftime(layout)}.{when.microsecond:06d}"


class Clock:
    """The time column and time fields of one run (see the module docstring)."""

    def __init__(self, fmt: str, t0: float | None) -> None:
        self.fmt = check_format(fmt)
        self.t0 = t0
        self.times: dict[int, float | None] = {}  # the latest records' times (`captured`), by number
        self.shown: float | None = None  # time of the last frame shown (`text`, `show`)

    def captured(self, number: int, time: float | None) -> None:
        """Every capture record, in capture order (a frame's previous record may be one without MAVLink)."""
        times = self.times
        times[number] = time
        if len(times) > _KEPT:  # (a frame is dated by a record at most a TCP hole's wait before the last)
            for old in list(times)[: len(times) - _KEPT // 2]:
                del times[old]

    def _previous(self, frame: Frame) -> tuple[float | None, float | None]:
        """The time of the record before the frame's, and of the last frame shown."""
        return self.times.get(frame.record - 1), self.shown

    def _deltas(self, frame: Frame, t: float) -> tuple[float, float]:
        prev, shown = self._previous(frame)
        return (0.0 if prev is None else (_us(t) - _us(prev)) / 1e6,
                0.0 if shown is None else (_us(t) - _us(shown)) / 1e6)

    def text(self, frame: Frame) -> str:
        """The time column of a shown frame, 11 wide as the relative time always was."""
        t = frame.time
        if t is None:
            return f"{'-':>11}"
        fmt = self.fmt
        if fmt == "r":
            out = f"{t - self.t0:.6f}" if self.t0 is not None else "-"
        elif fmt == "e":
            out = _ns(t)[:-3]
        elif fmt in ("d", "dd"):
            captured, shown = self._deltas(frame, t)
            out = f"{captured if fmt == 'd' else shown:.6f}"
        else:
            out = _wall(t, fmt)
        self.shown = t
        return f"{out:>11}"

    def show(self, frame: Frame) -> None:
        """A record's line was written (`-T fields`): the next one's `frame.time_delta_displayed` counts from it."""
        if frame.time is not None:
            self.shown = frame.time

    def field(self, name: str, frame: Frame) -> str:
        """A `frame.time*` field of a shown frame, as tshark prints it with -e: nine decimals, of which the
        capture's microseconds (the last three zero, as tshark prints a pcap's); empty without a time."""
        return self.at(name, frame.time, frame.record)

    def at(self, name: str, t: float | None, record: int) -> str:
        """`field` of a frame of capture record `record` captured at `t`."""
        if t is None:
            return ""
        if name == "frame.time":
            try:
                when = datetime.fromtimestamp(t).astimezone()
            except (OverflowError, OSError, ValueError):
                return _ns(t)
            return (f"{when.strftime('%b')} {when.day:2d}, {when.year} {when.strftime('%H:%M:%S')}."
                    f"{when.microsecond:06d}000 {when.strftime('%Z')}")
        if name == "frame.time_epoch":
            return _ns(t)
        if name == "frame.time_relative":
            return _ns(_us(t) - _us(self.t0), True) if self.t0 is not None else ""
        prev, shown = self.times.get(record - 1), self.shown
        base = prev if name == "frame.time_delta" else shown
        return _ns(0 if base is None else _us(t) - _us(base), True)


def _us(t: float) -> int:
    """A capture time in whole microseconds (what a pcap records; a float holds them to the nearest)."""
    return round(t * 1_000_000)


def _ns(t: float | int, micro: bool = False) -> str:
    """Seconds with nine decimals, as tshark's -e prints times: `t` in seconds, or in microseconds."""
    us = int(t) if micro else _us(t)
    sign, us = ("-", -us) if us < 0 else ("", us)
    return f"{sign}{us // 1_000_000}.{us % 1_000_000:06d}000"
