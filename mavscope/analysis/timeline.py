"""Clocks side by side per system: capture time against signature timestamps, SYSTEM_TIME, *_boot_ms
fields, TIMESYNC and PING, with offset and drift estimates and round-trip times.

Each clock a frame reveals becomes a sample (capture time, clock reading). Per (system, component,
source) a least-squares line through (capture time, reading - capture time) gives the offset (at the
capture's first frame) and the drift (its slope, in parts per million). Readings after 2001 in Unix
seconds are wall clocks (`unix`); smaller ones count from the sender's boot (`boot`), whose zero is given
as a capture time. A TIMESYNC answer (tc1 != 0) is dated at the middle of its round trip, since the
responder read its clock between request and answer. Capture time is the reference: the tool never
compares with the analyst's own clock.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import TypedDict

from mavscope.mavlink.frame import CrcStatus, Frame, decode_payload

UNIX_MIN = 1e9  # seconds: readings above this are wall-clock times (after 2001-09-09)


@dataclass
class Clock:
    sysid: int
    compid: int
    source: str
    samples: list[tuple[float, float]] = field(default_factory=list)  # (capture time, reading in seconds)

    @property
    def kind(self) -> str:
        return "unix" if self.samples and self.samples[0][1] > UNIX_MIN else "boot"

    def fit(self, at: float) -> tuple[float, float, float]:
        """(offset at capture time `at` in s, drift in ppm, RMS residual in ms)."""
        xs = [t for t, _ in self.samples]
        ys = [v - t for t, v in self.samples]
        n = len(xs)
        x0 = xs[0]
        mx = sum(x - x0 for x in xs) / n
        my = sum(ys) / n
        sxx = sum((x - x0 - mx) ** 2 for x in xs)
        slope = sum((x - x0 - mx) * (y - my) for x, y in zip(xs, ys)) / sxx if sxx > 0 else 0.0
        intercept = my - slope * mx
        resid = [y - (intercept + slope * (x - x0)) for x, y in zip(xs, ys)]
        rms = (sum(r * r for r in resid) / n) ** 0.5
        return intercept + slope * (at - x0), slope * 1e6, rms * 1000


@dataclass
class RoundTrips:
    requester: int
    responder: int
    kind: str  # "TIMESYNC" or "PING"
    rtt_ms: list[float] = field(default_factory=list)
    frames: list[tuple[int, int]] = field(default_factory=list)


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

    def to_json(self) -> dict[str, object]:
        systems: dict[int, _System] = {}
        at = self.start or 0.0
        for (sysid, compid, source), c in sorted(self.clocks.items()):
            if not c.samples:
                continue
            offset, drift, jitter = c.fit(at)
            entry: dict[str, object] = {
                "component": compid, "source": source, "kind": c.kind, "samples": len(c.samples),
                "offset_s": round(offset, 6), "drift_ppm": round(drift, 2), "jitter_ms": round(jitter, 3),
                "first": c.samples[0][0], "last": c.samples[-1][0],
            }
            if c.kind == "boot":
                entry["zero_at"] = round(-offset, 6)  # capture time at which this clock read zero
            systems.setdefault(sysid, {"sysid": sysid, "clocks": [], "round_trips": []})["clocks"].append(entry)
        for (kind, req, resp), rt in sorted(self.round_trips.items()):
            if not rt.rtt_ms:
                continue
            r = rt.rtt_ms
            systems.setdefault(req, {"sysid": req, "clocks": [], "round_trips": []})["round_trips"].append({
                "kind": kind, "peer": resp, "count": len(r), "min_ms": round(min(r), 3),
                "mean_ms": round(sum(r) / len(r), 3), "max_ms": round(max(r), 3),
                "rtt_ms": [round(x, 3) for x in r], "frames": [list(p) for p in rt.frames],
            })
        return {"start": self.start, "end": self.end,
                "duration": None if self.start is None or self.end is None else self.end - self.start,
                "systems": [systems[k] for k in sorted(systems)]}


def reconstruct(frames: Iterable[Frame]) -> Timeline:
    clocks: dict[tuple[int, int, str], Clock] = {}
    trips: dict[tuple[str, int, int], RoundTrips] = {}
    ts_requests: dict[int, tuple[int, float, int]] = {}  # ts1 -> (requester sysid, time, record)
    ping_requests: dict[tuple[int, int, int], tuple[float, int]] = {}  # (sysid, seq, time_usec) -> (time, record)
    start = end = None

    def sample(f: Frame, source: str, t: float, value: float) -> None:
        key = (f.sysid, f.compid, source)
        c = clocks.get(key)
        if c is None:
            c = clocks[key] = Clock(f.sysid, f.compid, source)
        c.samples.append((t, value))

    for f in frames:
        t = f.time
        if t is None:
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
                ts_requests[ts1] = (f.sysid, t, f.record)
                sample(f, "TIMESYNC.ts1", t, ts1 / 1e9)
            else:
                req = ts_requests.pop(ts1, None)
                if req is not None and req[0] != f.sysid:
                    rt = trips.setdefault(("TIMESYNC", req[0], f.sysid), RoundTrips(req[0], f.sysid, "TIMESYNC"))
                    rt.rtt_ms.append((t - req[1]) * 1000)
                    rt.frames.append((req[2], f.record))
                    sample(f, "TIMESYNC.tc1", (t + req[1]) / 2, tc1 / 1e9)
        elif name == "PING":
            tu, seq, target = int(fields["time_usec"]), int(fields["seq"]), int(fields["target_system"])  # type: ignore[call-overload]
            if target == 0:
                ping_requests[(f.sysid, seq, tu)] = (t, f.record)
                sample(f, "PING.time_usec", t, tu / 1e6)
            else:
                req2 = ping_requests.get((target, seq, tu))
                if req2 is not None:
                    rt = trips.setdefault(("PING", target, f.sysid), RoundTrips(target, f.sysid, "PING"))
                    rt.rtt_ms.append((t - req2[0]) * 1000)
                    rt.frames.append((req2[1], f.record))
    return Timeline(start, end, clocks, trips)
