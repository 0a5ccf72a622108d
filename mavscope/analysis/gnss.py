"""GNSS anomalies, the signs of GPS spoofing and jamming in a vehicle's telemetry (an expert detector).

- `gnss-position-jump`: consecutive positions (GLOBAL_POSITION_INT, GPS_RAW_INT, GPS2_RAW, each per sender)
  further apart than the reported ground speed can explain: more than JUMP_MIN_M and more than
  SPEED_FACTOR x the larger of the two speeds x the time between them, plus a margin for acceleration
  and for the receiver's accuracy. Positions within NULL_ISLAND degrees of 0, 0 are no position (ArduPilot
  reports offsets from 0, 0 until its EKF origin is set), GPS positions without a 2D fix are skipped.
- `gnss-fix-collapse`: a 3D fix with enough satellites falling, within COLLAPSE_WINDOW_S, to no fix or 2D
  (GPS_FIX_TYPE_NO_FIX / 2D_FIX), or to less than half the satellites and fewer than MIN_SATS (fix type 0,
  NO_GPS, is a receiver or its data feed going away, as ArduSub reports when its GPS_INPUT pauses: not a
  signal collapse).
- `ekf-gnss-alarm`: after the navigation filter was healthy (attitude, horizontal velocity and absolute
  horizontal position valid): ArduPilot's EKF_STATUS_REPORT or PX4's ESTIMATOR_STATUS reporting a GPS
  glitch, losing the absolute horizontal position, or a velocity or position innovation test ratio of 1
  or more (the level at which both autopilots reject the measurement).
- `gnss-time-jump`: the vehicle's UTC clock (SYSTEM_TIME.time_unix_usec, set from GNSS) stepping by more
  than TIME_JUMP_S against its own boot clock (time_boot_ms of the same message), with the step against
  capture time in the message; GPS_RAW_INT.time_usec, where it is a UTC time, disagreeing by more than
  TIME_MISMATCH_S with the UTC the last SYSTEM_TIME and the boot clock give.

Every interval is measured with the vehicle's own clocks (time_boot_ms, time_usec), never capture time:
a SITL run at 25x speed (ArduPilot autotest) must not look like a vehicle moving 25x too fast. A boot
clock that steps back is a reboot: the sender's state starts over. Bounded: MAX_SENDERS senders (every
system/component pair: none is given up) and MAX_EPISODES (kind, sender, message) episodes, 10 a sender at
most; past that an episode of the least established sender (fewest GNSS frames, in powers of two) is given
up for one of a sender with more, else the new one: a flood of made-up ids, each a few frames, cannot push
out the vehicle's, and what is given up is said (a `capacity` finding; docs/security.md, "Bounds").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from mavscope.analysis.framelist import frame_numbers
from mavscope.analysis.vehicles import MAX_SENDERS
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Addr, Frame
from mavscope.notes import Finding, FrameNumbers, GivenUp, finding

Fields = dict[str, object]

EARTH_RADIUS_M = 6_371_000.0
JUMP_MIN_M = 50.0  # a position step shorter than this is never a jump (receiver noise, EKF resets)
SPEED_FACTOR = 2.0  # the step may be this many times the distance the reported speed covers
ACCEL_MPS2 = 15.0  # plus what an acceleration this strong adds over the interval
MARGIN_M = 30.0  # plus this much for the receiver's accuracy (and 3x h_acc where reported)
NULL_ISLAND = 0.01  # degrees: positions this close to 0, 0 are "no position yet" (ArduPilot before its EKF
# origin is set reports offsets from 0, 0; the jump to the real position is no anomaly)
MAX_EPISODES = MAX_SENDERS  # episodes held
MAX_GAP_S = 10.0  # positions further apart in time than this are not compared (a gap, not a jump)
MIN_SATS = 6  # a fix with fewer satellites is weak
COLLAPSE_WINDOW_S = 5.0  # a collapse falls this soon after a good fix
VARIANCE_ALARM = 1.0  # innovation test ratio at which the measurement is rejected
TIME_JUMP_S = 2.0
TIME_MISMATCH_S = 5.0
UNIX_MIN_US = 10**15  # time_usec above this is a UTC time (after 2001-09-09), below it time since boot
REBOOT_BACK_S = 1.0
GPS_FIX_TYPE_NO_GPS, GPS_FIX_TYPE_NO_FIX, GPS_FIX_TYPE_2D, GPS_FIX_TYPE_3D = 0, 1, 2, 3
UNKNOWN_SATS = 255
UNKNOWN_VEL = 65535
POSITIONS = ("GLOBAL_POSITION_INT", "GPS_RAW_INT", "GPS2_RAW")
WANTS = frozenset(POSITIONS) | {"SYSTEM_TIME", "EKF_STATUS_REPORT", "ESTIMATOR_STATUS"}


def distance_m(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Great-circle distance (haversine) in metres between two points in degrees."""
    p1, p2 = math.radians(lat1), math.radians(lat2)
    dp, dl = p2 - p1, math.radians(lon2 - lon1)
    a = math.sin(dp / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(dl / 2) ** 2
    return 2 * EARTH_RADIUS_M * math.asin(min(1.0, math.sqrt(max(0.0, a))))


@dataclass
class _Fix:
    t: float  # s, the message's own clock
    lat: float
    lon: float
    speed: float | None  # m/s over ground
    record: int


@dataclass
class _Episodes:
    """The frames of one kind of anomaly of one sender, and the worst one's sentence."""

    frames: FrameNumbers = field(default_factory=frame_numbers)
    worst: float = -1.0
    text: str = ""

    def add(self, record: int, size: float, text: str) -> None:
        self.frames.add(record)
        if size > self.worst:
            self.worst, self.text = size, text


@dataclass(slots=True)
class _Sender:
    frames: int = 0  # its frames of WANTS: how established it is (the episodes of the fewest go first)
    fixes: dict[str, _Fix] = field(default_factory=dict)
    clocks: dict[str, float] = field(default_factory=dict)  # message -> last reading of its own clock (s)
    speed: float | None = None  # last ground speed of GLOBAL_POSITION_INT (for GPS_RAW_INT without one)
    good_fix: dict[str, tuple[float, int]] = field(default_factory=dict)  # message -> (time, satellites)
    collapsed: set[str] = field(default_factory=set)
    ekf_good: bool = False
    ekf_alarm: bool = False
    utc: tuple[float, float, float | None, int] | None = None  # SYSTEM_TIME: (unix s, boot s, capture t, record)
    boot_s: float | None = None  # the latest boot clock reading of any message


def _num(fields: Fields, name: str) -> float | None:
    v = fields.get(name)
    if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
        return float(v)
    return None


class GnssAnomalies:
    """Position jumps, fix collapses, EKF GNSS alarms and GNSS time jumps, per sender (see the module)."""

    wants = WANTS
    clean: frozenset[str | int] = WANTS  # what `add` reads (see expert.Detector)
    notes: frozenset[str] = frozenset()  # it reads its messages alone, whatever their notes

    def __init__(self, dialect: Dialect | None = None) -> None:
        self.senders: dict[Addr, _Sender] = {}
        self.found: dict[tuple[str, Addr, str], _Episodes] = {}  # (code, sender, message) -> episodes
        # the keys of `found` by how established their sender was (its frames' bit length) when last looked at
        self.tiers: list[dict[tuple[str, Addr, str], None]] = [{} for _ in range(65)]
        self.given_up = GivenUp(f"GNSS anomaly episodes (at most {MAX_EPISODES:,} (kind, sender, message) held)",
                                "episodes")
        ekf = dialect.enums.get("EKF_STATUS_FLAGS") if dialect is not None else None
        est = dialect.enums.get("ESTIMATOR_STATUS_FLAGS") if dialect is not None else None

        def flags(enum: object, names: tuple[str, ...]) -> int:
            by_name = getattr(enum, "by_name", {})
            return sum(by_name[n].value for n in names if n in by_name)

        # (healthy: every one of these bits, glitch bit, absolute horizontal position bit, uninitialised bit)
        self.ekf_bits = (flags(ekf, ("EKF_ATTITUDE", "EKF_VELOCITY_HORIZ", "EKF_POS_HORIZ_ABS")),
                         flags(ekf, ("EKF_GPS_GLITCHING",)), flags(ekf, ("EKF_POS_HORIZ_ABS",)),
                         flags(ekf, ("EKF_UNINITIALIZED",)))
        self.est_bits = (flags(est, ("ESTIMATOR_ATTITUDE", "ESTIMATOR_VELOCITY_HORIZ", "ESTIMATOR_POS_HORIZ_ABS")),
                         flags(est, ("ESTIMATOR_GPS_GLITCH",)), flags(est, ("ESTIMATOR_POS_HORIZ_ABS",)), 0)

    def _note(self, code: str, me: Addr, msg: str, record: int, size: float, text: str) -> None:
        key = (code, me, msg)
        ep = self.found.get(key)
        if ep is None:
            rank = self.senders[me].frames.bit_length()
            if len(self.found) >= MAX_EPISODES and not self._room(rank, key, record):
                self.given_up.add(f"{msg} {code} of {me[0]}/{me[1]} (frame {record}) not followed: every episode "
                                  "held is of a sender with as many GNSS frames", record=record)
                return
            ep = self.found[key] = _Episodes()
            self.tiers[rank][key] = None
        ep.add(record, size, text)

    def _room(self, rank: int, key: tuple[str, Addr, str], record: int) -> bool:
        """Give up the newest episode of the least established sender below `rank` (its frames' bit length) for
        `key`'s; False when every episode held is of a sender as established. An episode is looked at in the
        tier of its sender's frames when it was made: one whose sender has sent more since moves up first."""
        for low in range(rank):
            tier = self.tiers[low]
            while tier:
                gone = next(reversed(tier))
                del tier[gone]
                now = self.senders[gone[1]].frames.bit_length()
                if now != low:
                    self.tiers[now][gone] = None
                    continue
                ep = self.found.pop(gone)
                code, (sysid, compid), msg = gone
                self.given_up.add(f"{msg} {code} of {sysid}/{compid} ({ep.frames.count} frame(s)) given up for "
                                  f"{key[2]} {key[0]} of {key[1][0]}/{key[1][1]}, a sender with more GNSS frames",
                                  record=record)
                return True
        return False

    def add(self, f: Frame, fields: Fields | None) -> None:
        md = f.msgdef
        if fields is None or md is None or md.name not in WANTS:
            return
        me = (f.sysid, f.compid)
        s = self.senders.get(me)
        if s is None:
            if len(self.senders) >= MAX_SENDERS:
                return
            s = self.senders[me] = _Sender()
        s.frames += 1
        name = md.name
        if not self._clock(s, name, fields):
            return
        if name in POSITIONS:
            self._position(f, s, me, name, fields)
        elif name == "SYSTEM_TIME":
            self._system_time(f, s, me, fields)
        elif name == "EKF_STATUS_REPORT":
            self._ekf(f, s, me, name, fields, self.ekf_bits, ("velocity_variance", "pos_horiz_variance"))
        else:
            self._ekf(f, s, me, name, fields, self.est_bits, ("vel_ratio", "pos_horiz_ratio"))

    def _clock(self, s: _Sender, name: str, fields: Fields) -> bool:
        """Follow the message's own clock; a step back is a reboot (the sender's state starts over).
        False when the message has no usable clock."""
        boot = _num(fields, "time_boot_ms")
        usec = _num(fields, "time_usec")
        if boot is not None:
            now = boot / 1000
        elif usec is not None:
            now = usec / 1e6
        else:
            return name in ("EKF_STATUS_REPORT",)  # no clock of its own: judged in order
        last = s.clocks.get(name)
        if last is not None and now + REBOOT_BACK_S <= last and (usec is None or usec < UNIX_MIN_US):
            s.fixes.clear()
            s.good_fix.clear()
            s.collapsed.clear()
            s.ekf_good = s.ekf_alarm = False
            s.utc = None
            s.clocks.clear()
        s.clocks[name] = now
        if boot is not None:
            s.boot_s = now
        return True

    def _position(self, f: Frame, s: _Sender, me: Addr, name: str, fields: Fields) -> None:
        lat, lon = _num(fields, "lat"), _num(fields, "lon")
        if name == "GLOBAL_POSITION_INT":
            t = s.clocks[name]
            vx, vy = _num(fields, "vx"), _num(fields, "vy")
            speed = math.hypot(vx, vy) / 100 if vx is not None and vy is not None else None
            s.speed = speed
            accuracy = 0.0
        else:
            t = s.clocks[name]
            fix = fields.get("fix_type")
            if not isinstance(fix, int):
                return
            usec = _num(fields, "time_usec")
            if usec is not None and usec >= UNIX_MIN_US and fix >= GPS_FIX_TYPE_2D:
                self._gps_time(f, s, me, name, usec)
            self._fix(f, s, me, name, t, fix, fields.get("satellites_visible"))
            if fix < GPS_FIX_TYPE_2D:
                s.fixes.pop(name, None)
                return
            vel = fields.get("vel")
            speed = vel / 100 if isinstance(vel, int) and vel != UNKNOWN_VEL else s.speed
            h_acc = fields.get("h_acc")
            accuracy = 3 * h_acc / 1000 if isinstance(h_acc, int) and 0 < h_acc < 10**7 else 0.0
        if lat is None or lon is None:
            return
        lat, lon = lat / 1e7, lon / 1e7
        if not (-90 <= lat <= 90 and -180 <= lon <= 180) or (abs(lat) < NULL_ISLAND and abs(lon) < NULL_ISLAND):
            return
        prev = s.fixes.get(name)
        s.fixes[name] = _Fix(t, lat, lon, speed, f.record)
        if prev is None:
            return
        dt = t - prev.t
        if dt <= 0 or dt > MAX_GAP_S or speed is None or prev.speed is None:
            return
        d = distance_m(prev.lat, prev.lon, lat, lon)
        v = max(speed, prev.speed)
        allowed = SPEED_FACTOR * v * dt + 0.5 * ACCEL_MPS2 * dt * dt + MARGIN_M + accuracy
        if d >= JUMP_MIN_M and d > allowed:
            self._note("gnss-position-jump", me, name, f.record, d, jump_text(d, dt, v, prev.record, f.record, allowed))

    def _fix(self, f: Frame, s: _Sender, me: Addr, name: str, t: float, fix: int, sats: object) -> None:
        nsat = sats if isinstance(sats, int) and sats != UNKNOWN_SATS else None
        if fix >= GPS_FIX_TYPE_3D and (nsat is None or nsat >= MIN_SATS):
            s.good_fix[name] = (t, nsat if nsat is not None else -1)
            s.collapsed.discard(name)
            return
        good = s.good_fix.get(name)
        if good is None or name in s.collapsed or fix == GPS_FIX_TYPE_NO_GPS:
            return
        if not 0 <= t - good[0] <= COLLAPSE_WINDOW_S:
            return
        weak = fix in (GPS_FIX_TYPE_NO_FIX, GPS_FIX_TYPE_2D)
        few = nsat is not None and good[1] > 0 and nsat * 2 < good[1] and nsat < MIN_SATS
        if weak or few:
            s.collapsed.add(name)
            self._note("gnss-fix-collapse", me, name, f.record, float(good[1] - (nsat or 0)),
                       collapse_text(good[1], nsat, fix, t - good[0], f.record))

    def _ekf(self, f: Frame, s: _Sender, me: Addr, name: str, fields: Fields, bits: tuple[int, int, int, int],
             ratios: tuple[str, str]) -> None:
        healthy, glitch, pos_abs, uninit = bits
        flags = fields.get("flags")
        if not isinstance(flags, int) or not healthy:
            return
        if uninit and flags & uninit:  # the filter starting over (a reboot, a reset): not an alarm
            s.ekf_good = s.ekf_alarm = False
            return
        worst = max((v for v in (_num(fields, r) for r in ratios) if v is not None), default=0.0)
        why = ekf_reasons(bool(glitch and flags & glitch), not flags & pos_abs,
                          worst if worst >= VARIANCE_ALARM else None)
        if not why and flags & healthy == healthy:
            s.ekf_good, s.ekf_alarm = True, False
            return
        if s.ekf_good and why and not s.ekf_alarm:
            s.ekf_alarm = True
            self._note("ekf-gnss-alarm", me, name, f.record, worst + len(why), ekf_text(why, flags, f.record))

    def _system_time(self, f: Frame, s: _Sender, me: Addr, fields: Fields) -> None:
        unix, boot = _num(fields, "time_unix_usec"), _num(fields, "time_boot_ms")
        if unix is None or boot is None or unix == 0 or boot == 0:  # no UTC yet; ground stations send boot 0
            return
        u, b = unix / 1e6, boot / 1000
        prev = s.utc
        s.utc = (u, b, f.time, f.record)
        if prev is None or b < prev[1]:
            return
        step = (u - b) - (prev[0] - prev[1])
        if abs(step) > TIME_JUMP_S:
            against = (u - f.time) - (prev[0] - prev[2]) if f.time is not None and prev[2] is not None else None
            self._note("gnss-time-jump", me, "SYSTEM_TIME", f.record, abs(step),
                       time_jump_text(step, prev[3], f.record, against))

    def _gps_time(self, f: Frame, s: _Sender, me: Addr, name: str, usec: float) -> None:
        """A UTC time_usec against the UTC that the last SYSTEM_TIME and the boot clock give now."""
        if s.utc is None or s.boot_s is None or s.boot_s < s.utc[1]:
            return
        expected = s.utc[0] + (s.boot_s - s.utc[1])
        diff = usec / 1e6 - expected
        if abs(diff) > TIME_MISMATCH_S:
            self._note("gnss-time-jump", me, name, f.record, abs(diff), gps_time_text(name, diff, s.utc[3], f.record))

    def findings(self) -> list[Finding]:
        out = []
        what = {"gnss-position-jump": "position jumps the reported speed cannot explain",
                "gnss-fix-collapse": "GNSS fix collapses", "ekf-gnss-alarm": "navigation filter GNSS alarms",
                "gnss-time-jump": "GNSS time jumps"}
        for (code, (sysid, compid), msg), ep in self.found.items():
            out.append(finding(code, f"{msg} of {sysid}/{compid}: {ep.frames.count} {what[code]}; the largest: "
                                     f"{ep.text}", ep.frames.nums))
        said = self.given_up.finding()
        return out if said is None else [*out, said]


# The sentences of the worst episode of each kind
def jump_text(d: float, dt: float, v: float, before: int, record: int, allowed: float) -> str:
    return (f"{d:.0f} m in {dt:.2f} s while reporting {v:.1f} m/s (frames {before} -> {record}; at most "
            f"{allowed:.0f} m expected)")


def collapse_text(good: int, nsat: int | None, fix: int, dt: float, record: int) -> str:
    was = f"{good} satellites, 3D fix" if good >= 0 else "a 3D fix"
    now = f"{nsat} satellites, fix type {fix}" if nsat is not None else f"fix type {fix}"
    return f"{was} -> {now} within {dt:.1f} s (frame {record})"


def ekf_reasons(glitch: bool, position_lost: bool, ratio: float | None) -> list[str]:
    """Why the navigation filter's report is an alarm (`ratio`: the worst innovation test ratio when it is
    one); empty when it is none."""
    why = []
    if glitch:
        why.append("GPS glitch flag")
    if position_lost:
        why.append("absolute horizontal position lost")
    if ratio is not None:
        why.append(f"innovation test ratio {ratio:.2f}")
    return why


def ekf_text(why: list[str], flags: int, record: int) -> str:
    return f"{', '.join(why)} (flags 0x{flags:x}, frame {record})"


def time_jump_text(step: float, before: int, record: int, against: float | None) -> str:
    cap = "" if against is None else f"; against capture time {against:+.1f} s"
    return f"UTC {step:+.1f} s against the boot clock (frames {before} -> {record}{cap})"


def gps_time_text(name: str, diff: float, utc_record: int, record: int) -> str:
    return (f"{name}.time_usec {diff:+.1f} s from the UTC of SYSTEM_TIME (frame {utc_record}) and the boot clock "
            f"(frame {record})")
