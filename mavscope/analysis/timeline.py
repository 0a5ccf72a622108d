"""Clocks side by side per system: capture time against signature timestamps, SYSTEM_TIME, *_boot_ms
fields, TIMESYNC and PING, with offset and drift estimates and round-trip times.

Each clock a frame reveals becomes a sample (capture time, clock reading). Per (system, component,
source) a least-squares line through (capture time, reading - capture time) gives the offset (at the
capture's first frame) and the drift (its slope, in parts per million) with its standard error. The fit is
accumulated online (Welford's sums), so a clock costs the same memory whatever the capture's length. A
drift is given only from enough samples over enough time (DRIFT_MIN_SAMPLES over DRIFT_MIN_SPAN seconds):
four samples in half a second do not measure a drift of -9105.9 ppm. Without one, the line is flat: the
offset is the samples' mean.

A clock that steps back by more than RESTART_BACK seconds restarted (a reboot: `time_boot_ms` starts
again from zero; or a wall clock set back): one line cannot go through both runs, so the fit starts over
and the clock reports how often and when it restarted; offset, drift and zero describe its last run.

Readings after 2001 in Unix seconds are wall clocks (`unix`); smaller ones count from the sender's boot
(`boot`), whose zero is given as a capture time. A TIMESYNC answer (tc1 != 0) is dated at the middle of
its round trip, since the responder read its clock between request and answer. Capture time is the
reference: the tool never compares with the analyst's own clock.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import TypedDict

from mavscope.analysis.selection import Selection
from mavscope.mavlink.frame import CrcStatus, Frame, decode_payload
from mavscope.notes import GivenUp, pop_newest

UNIX_MIN = 1e9  # seconds: readings above this are wall-clock times (after 2001-09-09)
DRIFT_MIN_SAMPLES = 10
DRIFT_MIN_SPAN = 10.0  # seconds
RESTART_BACK = 1.0  # seconds a clock must step back to have restarted (less is jitter or a late frame)
RESTARTS_LISTED = 20  # capture times of restarts listed per clock (all of them are counted)
ROUND_TRIPS_LISTED = 1000  # round-trip times listed per pair (all of them are counted)
PENDING_REQUESTS = 4096  # TIMESYNC/PING requests waiting for their answer (past it the newest go, said)
MAX_CLOCKS = 16_384  # clocks followed: a capture names up to 65,280 senders x 256 signing links (the later
# ones are counted, not followed: a real capture has tens)


@dataclass(slots=True)
class Clock:
    """One clock's samples, as running sums of the least-squares fit (x: capture time from the first
    sample, y: reading - capture time)."""

    sysid: int
    compid: int
    source: str
    n: int = 0
    x0: float = 0.0
    first: float = 0.0
    last: float = 0.0
    first_reading: float = 0.0
    mean_x: float = 0.0
    mean_y: float = 0.0
    sxx: float = 0.0  # sum of squared deviations of x
    syy: float = 0.0
    sxy: float = 0.0
    reading: float = 0.0  # the last one
    restarts: int = 0
    restarted_at: list[float] = field(default_factory=list)  # capture times, the first RESTARTS_LISTED

    def add(self, t: float, reading: float) -> None:
        if self.n and reading < self.reading - RESTART_BACK:
            self.restarts += 1
            if len(self.restarted_at) < RESTARTS_LISTED:
                self.restarted_at.append(t)
            self.n = 0
            self.mean_x = self.mean_y = self.sxx = self.syy = self.sxy = 0.0
        self.reading = reading
        if self.n == 0:
            self.x0, self.first, self.first_reading = t, t, reading
        self.last = t
        x, y = t - self.x0, reading - t
        self.n += 1
        dx = x - self.mean_x
        dy = y - self.mean_y
        self.mean_x += dx / self.n
        self.mean_y += dy / self.n
        self.sxx += dx * (x - self.mean_x)
        self.syy += dy * (y - self.mean_y)
        self.sxy += dx * (y - self.mean_y)

    @property
    def kind(self) -> str:
        return "unix" if self.n and self.first_reading > UNIX_MIN else "boot"

    def fit(self, at: float) -> tuple[float, float, float, float | None]:
        """(offset at capture time `at` in s, drift in ppm, RMS residual in ms, drift standard error in ppm
        or None with fewer than three samples). Where the samples do not measure a drift (`measures_drift`)
        the line is flat: the offset is their mean, not the intercept of a slope they cannot tell (ArduPilot's
        signing clock over 2.3 s, stepping 8.7 s forward at the end, put it at -11.8 s, below every sample:
        -10.1 s to -1.4 s)."""
        slope = self.sxy / self.sxx if self.sxx > 0 and self.measures_drift else 0.0
        intercept = self.mean_y - slope * self.mean_x
        resid = max(0.0, self.syy - slope * self.sxy)  # sum of squared residuals
        rms = math.sqrt(resid / self.n) if self.n else 0.0
        err = math.sqrt(resid / (self.n - 2) / self.sxx) * 1e6 if self.n > 2 and self.sxx > 0 else None
        return intercept + slope * (at - self.x0), slope * 1e6, rms * 1000, err

    @property
    def measures_drift(self) -> bool:
        return self.n >= DRIFT_MIN_SAMPLES and self.last - self.first >= DRIFT_MIN_SPAN


@dataclass
class RoundTrips:
    requester: int
    responder: int
    kind: str  # "TIMESYNC" or "PING"
    count: int = 0
    total_ms: float = 0.0
    min_ms: float = math.inf
    max_ms: float = -math.inf
    rtt_ms: list[float] = field(default_factory=list)  # the first ROUND_TRIPS_LISTED
    frames: list[tuple[int, int]] = field(default_factory=list)

    def add(self, rtt_ms: float, request: int, answer: int) -> None:
        self.count += 1
        self.total_ms += rtt_ms
        self.min_ms = min(self.min_ms, rtt_ms)
        self.max_ms = max(self.max_ms, rtt_ms)
        if len(self.rtt_ms) < ROUND_TRIPS_LISTED:
            self.rtt_ms.append(rtt_ms)
            self.frames.append((request, answer))


class _System(TypedDict):
    """One system's entry in `Timeline.to_json`."""

    sysid: int
    clocks: list[dict[str, object]]
    round_trips: list[dict[str, object]]


@dataclass
class Timeline:
    start: float | None
    end: float | None
    clocks: dict[tuple[int, int, str], Clock]
    round_trips: dict[tuple[str, int, int], RoundTrips]
    unfollowed: int = 0  # readings of clocks beyond the first MAX_CLOCKS (not followed)
    given_up: tuple[GivenUp, ...] = ()  # requests no longer waited for (PENDING_REQUESTS): TIMESYNC, PING

    def to_json(self, select: Selection | None = None) -> dict[str, object]:
        """The `timeline --json` document (the systems `select` selects; all without it)."""
        systems: dict[int, _System] = {}
        at = self.start or 0.0
        for (sysid, compid, source), c in sorted(self.clocks.items()):
            if not c.n or (select is not None and not select.system(sysid)):
                continue
            offset, drift, jitter, err = c.fit(at)
            measured = c.measures_drift
            entry: dict[str, object] = {
                "component": compid, "source": source, "kind": c.kind, "samples": c.n,
                "offset_s": round(offset, 6), "drift_ppm": round(drift, 2) if measured else None,
                "drift_err_ppm": round(err, 2) if measured and err is not None else None,
                "jitter_ms": round(jitter, 3), "first": c.first, "last": c.last,
                "restarts": c.restarts, "restarted_at": c.restarted_at,
            }
            if c.kind == "boot":
                entry["zero_at"] = round(-offset, 6)  # capture time at which this clock read zero
            systems.setdefault(sysid, {"sysid": sysid, "clocks": [], "round_trips": []})["clocks"].append(entry)
        for (kind, req, resp), rt in sorted(self.round_trips.items()):
            if not rt.count or (select is not None and not (select.system(req) or select.system(resp))):
                continue
            systems.setdefault(req, {"sysid": req, "clocks": [], "round_trips": []})["round_trips"].append({
                "kind": kind, "peer": resp, "count": rt.count, "min_ms": round(rt.min_ms, 3),
                "mean_ms": round(rt.total_ms / rt.count, 3), "max_ms": round(rt.max_ms, 3),
                "rtt_ms": [round(x, 3) for x in rt.rtt_ms], "frames": [list(p) for p in rt.frames],
            })
        return {"start": self.start, "end": self.end,
                "duration": None if self.start is None or self.end is None else self.end - self.start,
                "systems": [systems[k] for k in sorted(systems)], "unfollowed_readings": self.unfollowed,
                "findings": [f.to_json() for g in self.given_up if (f := g.finding()) is not None]}


class _Pending(OrderedDict[object, tuple[int, float, int]]):
    """Requests waiting for their answer, at most PENDING_REQUESTS: past it the newest but the one just made
    is given up (notes.pop_newest: a flood of requests gives up its own, never those waiting before it), said
    (`given_up`, a `capacity` finding)."""

    def __init__(self, what: str) -> None:
        super().__init__()
        self.given_up = GivenUp(f"{what} requests waiting for their answer (at most {PENDING_REQUESTS:,})",
                                "requests")

    def put(self, key: object, value: tuple[int, float, int]) -> None:
        self[key] = value
        if len(self) > PENDING_REQUESTS:
            _, (sysid, _, record) = pop_newest(self, key)
            self.given_up.add(f"the request of system {sysid} in frame {record} is no longer waited for: its "
                              "round trip is not measured", record=value[2])


def reconstruct(frames: Iterable[Frame]) -> Timeline:
    """The clocks and round trips of `frames` (in capture order), in one pass and bounded state."""
    clocks: dict[tuple[int, int, str], Clock] = {}
    trips: dict[tuple[str, int, int], RoundTrips] = {}
    ts_requests = _Pending("TIMESYNC")  # ts1 -> (requester sysid, time, record)
    ping_requests = _Pending("PING")  # (sysid, seq, time_usec) -> (sysid, time, record)
    start = end = None
    unfollowed = 0

    def sample(f: Frame, source: str, t: float, value: float) -> None:
        nonlocal unfollowed
        key = (f.sysid, f.compid, source)
        c = clocks.get(key)
        if c is None:
            if len(clocks) >= MAX_CLOCKS:
                unfollowed += 1
                return
            c = clocks[key] = Clock(f.sysid, f.compid, source)
        c.add(t, value)

    def trip(kind: str, requester: int, responder: int) -> RoundTrips:
        rt = trips.get((kind, requester, responder))
        if rt is None:
            rt = trips[(kind, requester, responder)] = RoundTrips(requester, responder, kind)
        return rt

    for f in frames:
        t = f.time
        if t is None or not math.isfinite(t):
            continue
        if start is None:
            start = t
        end = t
        if f.signature is not None:
            sample(f, f"signature link {f.signature.link_id}", t, f.signature.unix_time)
        md = f.msgdef
        if md is None or f.crc_status is CrcStatus.BAD:
            continue
        name = md.name
        has_boot = md.field("time_boot_ms") is not None
        if not has_boot and name not in ("SYSTEM_TIME", "TIMESYNC", "PING"):
            continue
        fields = decode_payload(f)
        if fields is None:
            continue
        if has_boot:
            sample(f, f"{name}.time_boot_ms" if name == "SYSTEM_TIME" else "time_boot_ms", t,
                   int(fields["time_boot_ms"]) / 1000)  # type: ignore[call-overload]
        if name == "SYSTEM_TIME":
            unix = int(fields["time_unix_usec"])  # type: ignore[call-overload]
            if unix:
                sample(f, "SYSTEM_TIME.time_unix_usec", t, unix / 1e6)
        elif name == "TIMESYNC":
            tc1, ts1 = int(fields["tc1"]), int(fields["ts1"])  # type: ignore[call-overload]
            if tc1 == 0:
                ts_requests.put(ts1, (f.sysid, t, f.record))
                sample(f, "TIMESYNC.ts1", t, ts1 / 1e9)
            else:
                req = ts_requests.pop(ts1, None)
                if req is not None and req[0] != f.sysid:
                    trip("TIMESYNC", req[0], f.sysid).add((t - req[1]) * 1000, req[2], f.record)
                    sample(f, "TIMESYNC.tc1", (t + req[1]) / 2, tc1 / 1e9)
        elif name == "PING":
            tu, seq, target = int(fields["time_usec"]), int(fields["seq"]), int(fields["target_system"])  # type: ignore[call-overload]
            if target == 0:
                ping_requests.put((f.sysid, seq, tu), (f.sysid, t, f.record))
                sample(f, "PING.time_usec", t, tu / 1e6)
            else:
                req2 = ping_requests.get((target, seq, tu))
                if req2 is not None:
                    trip("PING", target, f.sysid).add((t - req2[1]) * 1000, req2[2], f.record)
    return Timeline(start, end, clocks, trips, unfollowed, (ts_requests.given_up, ping_requests.given_up))
