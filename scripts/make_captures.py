#!/usr/bin/env python3
"""Build mavscope's sample captures, byte for byte the same on every run and machine.

    python scripts/make_captures.py [OUTDIR]        (default: the repository's captures/)

MAVLink frames are encoded (and signed) by pymavlink, an implementation independent of mavscope's
decoder, so the two can be checked against each other. Ethernet/IP/UDP/TCP headers, with correct
checksums, are built by scapy. The capture files themselves (pcap, pcapng, tlog, raw) are written
with `struct`: scapy's writers take time from float seconds (rounding) or from the wall clock when a
packet has none, and its pcapng writer cannot give two interfaces different time resolutions.

Determinism: a fixed base time, one seeded `random.Random` per capture, integer microsecond (or
nanosecond) timestamps, explicit MAC/IP addresses, IP ids, TCP sequence numbers and signing
timestamps; floats are computed with + - * / only (no libm calls whose last bit may differ between
platforms). Nothing reads the clock or the environment.

Besides the captures the script writes `expected.json` (what a correct decoder must report, computed
from what was generated, not by decoding) and `README.md` (the same in prose).
"""

from __future__ import annotations

import hashlib
import json
import struct
import sys
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from random import Random
from types import ModuleType
from typing import Any

import pymavlink.dialects.v10.common as mav1
import pymavlink.dialects.v20.common as mav2
from scapy.layers.inet import IP, TCP, UDP
from scapy.layers.inet6 import IPv6
from scapy.layers.l2 import ARP, Dot1Q, Ether
from scapy.packet import Packet as ScapyPacket
from scapy.packet import Raw

# --------------------------------------------------------------------------------------------------
# Constants
# --------------------------------------------------------------------------------------------------

REPO = Path(__file__).resolve().parent.parent
DEFAULT_OUTDIR = REPO / "captures"

BASE_TIME_US = 1_773_482_400 * 1_000_000  # 2026-03-14T10:00:00Z
SIGNING_EPOCH_US = 1_420_070_400 * 1_000_000  # 2015-01-01T00:00:00Z: MAVLink signing timestamps
VEHICLE_BOOT_OFFSET_MS = 41_317  # the vehicle booted this long before the capture starts
VEHICLE_UTC_OFFSET_US = 2_150  # the vehicle's UTC clock (SYSTEM_TIME, GPS) runs this much ahead

SIGNING_PASSPHRASE = "mavscope-demo"
SIGNING_KEY = hashlib.sha256(SIGNING_PASSPHRASE.encode()).digest()  # as MAVProxy derives keys
VEHICLE_LINK_ID = 0
GCS_LINK_ID = 1

# PX4 SITL default home (Zurich) and the metres-per-degree factors around it.
HOME_LAT_DEG = 47.3977419
HOME_LON_DEG = 8.5455938
HOME_ALT_M = 488.0
M_PER_DEG_LAT = 111_320.0
M_PER_DEG_LON = 111_320.0 * 0.6769049796852641  # cos(47.3977419 deg), written out: no libm at run time
DEG_TO_RAD = 0.017453292519943295

VEHICLE_SYSID, VEHICLE_COMPID = 1, 1
GCS_SYSID, GCS_COMPID = 255, 190
LOOPBACK_V4 = "127.0.0.1"
VEHICLE_UDP_PORT, GCS_UDP_PORT = 14580, 14550
ARDUPILOT_TCP_PORT, GCS_TCP_PORT = 5760, 40412
ZERO_MAC = "00:00:00:00:00:00"  # Linux loopback as tcpdump -i lo records it
SYN_WINDOW = {"S": 65_495, "SA": 65_483}  # Linux on lo; later segments: 512 << 7 (window scale)

LINKTYPE_ETHERNET = 1
LINKTYPE_LINUX_SLL2 = 276
SNAPLEN = 262_144

UNKNOWN_MSGID = 65_000  # in no pymavlink 2.4.50 dialect (60000 is STorM32's, and so in all.xml)
UNKNOWN_INCOMPAT_FLAG = 0x02  # not SIGNED (0x01), not the SecureMAV cipher bits (0xE0)

# MAVLink enum values used below (common.xml / minimal.xml).
MAV_TYPE_QUADROTOR, MAV_TYPE_GCS = 2, 6
MAV_AUTOPILOT_ARDUPILOTMEGA, MAV_AUTOPILOT_INVALID, MAV_AUTOPILOT_PX4 = 3, 8, 12
MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, MAV_MODE_FLAG_SAFETY_ARMED = 1, 128
MAV_MODE_FLAG_STABILIZE_ENABLED, MAV_MODE_FLAG_GUIDED_ENABLED, MAV_MODE_FLAG_AUTO_ENABLED = 16, 8, 4
MAV_MODE_FLAG_MANUAL_INPUT_ENABLED = 64
MAV_STATE_STANDBY, MAV_STATE_ACTIVE = 3, 4
MAV_FRAME_GLOBAL_RELATIVE_ALT_INT = 6
MAV_CMD_NAV_WAYPOINT, MAV_CMD_NAV_RETURN_TO_LAUNCH, MAV_CMD_NAV_TAKEOFF = 16, 20, 22
MAV_CMD_DO_REPOSITION, MAV_CMD_COMPONENT_ARM_DISARM = 192, 400
MAV_RESULT_ACCEPTED, MAV_MISSION_ACCEPTED, MAV_MISSION_TYPE_MISSION = 0, 0, 0
MAV_SEVERITY_WARNING, MAV_SEVERITY_INFO = 4, 6
GPS_FIX_TYPE_3D_FIX = 3
NAN = float("nan")  # PX4/QGC send NaN for "unchanged" (yaw); packs to 00 00 c0 7f on every platform

# PX4 custom_mode = sub_mode << 24 | main_mode << 16; ArduCopter custom_mode = mode number.
PX4_MODES = {"HOLD": 0x0304_0000, "MISSION": 0x0404_0000, "RTL": 0x0504_0000}
ARDUCOPTER_MODES = {"HOLD": 5, "MISSION": 3, "RTL": 6}  # LOITER, AUTO, RTL
SENSORS_PRESENT = 0x3520_FC2F  # gyro, accel, mag, baro, GPS, ... as PX4 reports them

# --------------------------------------------------------------------------------------------------
# Frames and senders
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Frame:
    """One MAVLink frame as generated, with what a decoder must find in it."""

    data: bytes
    sysid: int
    compid: int
    seq: int
    msgid: int
    version: int  # 1 or 2
    signed: bool = False
    crc: str = "ok"  # "ok", "bad" or "unchecked" (message id unknown, so CRC_EXTRA unknown)


class Endpoint:
    """One MAVLink sender (a vehicle or a GCS): pymavlink does the encoding, signing and sequencing."""

    def __init__(self, dialect: ModuleType, sysid: int, compid: int, *, link_id: int | None = None) -> None:
        self.dialect = dialect
        self.v1 = dialect.WIRE_PROTOCOL_VERSION == "1.0"
        self.mav: Any = dialect.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        if link_id is not None:
            # Set by hand rather than through mavutil.setup_signing(), which takes time.time().
            self.mav.signing.secret_key = SIGNING_KEY
            self.mav.signing.sign_outgoing = True
            self.mav.signing.link_id = link_id

    def pack(self, msg: Any, t_us: int) -> Frame:
        """Encode `msg` as sent at capture time `t_us` and advance the sequence number."""
        mav = self.mav
        signed = mav.signing.sign_outgoing
        if signed:  # signature timestamps follow the capture clock and never go backwards
            mav.signing.timestamp = max(mav.signing.timestamp, (t_us - SIGNING_EPOCH_US) // 10)
        seq = mav.seq
        data = msg.pack(mav)
        mav.seq = (mav.seq + 1) % 256
        return Frame(data, mav.srcSystem, mav.srcComponent, seq, msg.get_msgId(), 1 if self.v1 else 2, signed)

    def next_seq(self) -> int:
        """Take a sequence number for a frame built by hand."""
        seq = self.mav.seq
        self.mav.seq = (seq + 1) % 256
        return seq


def v2_frame(msgid: int, payload: bytes, seq: int, sysid: int, compid: int, crc_extra: int,
             incompat: int = 0) -> bytes:
    """A MAVLink v2 frame built by hand (for message ids or flags pymavlink will not produce)."""
    header = struct.pack("<BBBBBBBHB", 0xFD, len(payload), incompat, 0, seq, sysid, compid,
                         msgid & 0xFFFF, msgid >> 16)
    crc = mav2.x25crc(header[1:] + payload)
    crc.accumulate(bytes([crc_extra]))
    return header + payload + struct.pack("<H", crc.crc)


def frame_crc_ok(data: bytes) -> bool:
    """Whether a complete v1/v2 frame of a common.xml message has a good CRC (for self-checks)."""
    if data[0] == 0xFE:
        hlen, msgid = 6, data[5]
    else:
        hlen, msgid = 10, data[7] | data[8] << 8 | data[9] << 16
    end = hlen + data[1]
    crc = mav2.x25crc(data[1:end])
    crc.accumulate(bytes([mav2.mavlink_map[msgid].crc_extra]))
    return struct.unpack_from("<H", data, end)[0] == crc.crc


def assert_no_stx(data: bytes, what: str) -> None:
    """Damaged bytes must not hide a 0xFD/0xFE that could start another candidate frame."""
    if b"\xfd" in data or b"\xfe" in data:
        raise AssertionError(f"{what} contains a MAVLink start byte: {data.hex()}")


# --------------------------------------------------------------------------------------------------
# Scenario: a flight story, telemetry streams and the GCS's requests
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Keyframe:
    t: float  # seconds since the capture start
    north: float  # metres from home
    east: float
    alt: float  # metres above home
    heading: float  # degrees


@dataclass(frozen=True)
class Story:
    """What happens in a session. Times in seconds from the capture start; None = does not happen."""

    duration: float
    keyframes: tuple[Keyframe, ...]
    mission_at: float | None = None
    arm_at: float | None = None
    reposition_at: float | None = None
    rtl_at: float | None = None
    landed_at: float | None = None
    statustexts: tuple[tuple[float, int, str], ...] = ()
    waypoints: tuple[tuple[float, float, float], ...] = ()  # (north, east, alt) of the mission's two WPs
    reposition_to: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class VehicleState:
    lat: int  # degE7
    lon: int
    rel_alt: float  # m above home
    vn: float  # m/s
    ve: float
    vd: float
    heading: float  # deg
    armed: bool
    mode: str  # key of PX4_MODES


def to_degE7(north: float, east: float) -> tuple[int, int]:
    """Metres from home to integer degrees * 1e7."""
    return (round((HOME_LAT_DEG + north / M_PER_DEG_LAT) * 1e7),
            round((HOME_LON_DEG + east / M_PER_DEG_LON) * 1e7))


def vehicle_state(story: Story, t: float) -> VehicleState:
    """Position by linear interpolation between keyframes; flags from the story's events."""
    kfs = story.keyframes
    a, b = kfs[0], kfs[-1]
    for k0, k1 in zip(kfs, kfs[1:]):
        if k0.t <= t < k1.t:
            a, b = k0, k1
            break
    else:
        a = b = kfs[0] if t < kfs[0].t else kfs[-1]
    span = b.t - a.t
    f = (t - a.t) / span if span > 0 else 0.0
    north, east = a.north + (b.north - a.north) * f, a.east + (b.east - a.east) * f
    alt = a.alt + (b.alt - a.alt) * f
    vn, ve, vu = ((b.north - a.north) / span, (b.east - a.east) / span, (b.alt - a.alt) / span) \
        if span > 0 else (0.0, 0.0, 0.0)
    lat, lon = to_degE7(north, east)
    armed = story.arm_at is not None and story.arm_at + 0.05 <= t \
        and not (story.landed_at is not None and t >= story.landed_at)
    mode = "HOLD"
    if armed:
        mode = "MISSION"
    if story.reposition_at is not None and t >= story.reposition_at + 0.05:
        mode = "HOLD"
    if story.rtl_at is not None and t >= story.rtl_at + 0.05:
        mode = "RTL"
    return VehicleState(lat, lon, alt, vn, ve, -vu, a.heading + (b.heading - a.heading) * f, armed, mode)


MessageFactory = Callable[[Any, VehicleState, int], Any]  # (mav, state, t_us) -> message


@dataclass(frozen=True)
class Stream:
    """A periodic telemetry message."""

    name: str
    period_ms: int
    phase_ms: int
    factory: MessageFactory


@dataclass
class Send:
    """One write by one endpoint: the payload of one UDP datagram, or a chunk written to a stream."""

    t_us: int  # microseconds since the capture start
    side: str  # "vehicle" or "gcs"
    frames: list[Frame]
    urgent: bool = False  # a reply in a transaction: a stream writer flushes it at once


@dataclass(order=True)
class Intent:
    """A planned Send: message factories, packed in time order so sequence numbers come out right."""

    t_us: int
    order: int
    side: str = field(compare=False)
    factories: list[MessageFactory] = field(compare=False)
    urgent: bool = field(default=False, compare=False)


@dataclass(frozen=True)
class Profile:
    """Who talks: the dialect, the autopilot flavour, signing, and which telemetry streams."""

    dialect: ModuleType
    autopilot: int
    streams: tuple[str, ...]
    vehicle_sysid: int = VEHICLE_SYSID
    signed: bool = False
    bundle_p: float = 0.2  # chance that frames due at the same tick share one datagram


def _custom_mode(autopilot: int, mode: str) -> int:
    return (PX4_MODES if autopilot == MAV_AUTOPILOT_PX4 else ARDUCOPTER_MODES)[mode]


def _heartbeat(autopilot: int) -> MessageFactory:
    def build(mav: Any, s: VehicleState, t_us: int) -> Any:
        base = MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | MAV_MODE_FLAG_STABILIZE_ENABLED
        if s.mode != "HOLD" or s.armed:
            base |= MAV_MODE_FLAG_GUIDED_ENABLED | MAV_MODE_FLAG_AUTO_ENABLED
        if s.armed:
            base |= MAV_MODE_FLAG_SAFETY_ARMED
        return mav.heartbeat_encode(MAV_TYPE_QUADROTOR, autopilot, base, _custom_mode(autopilot, s.mode),
                                    MAV_STATE_ACTIVE if s.armed else MAV_STATE_STANDBY, 3)
    return build


def telemetry_streams(profile: Profile, rng: Random) -> list[Stream]:
    """The vehicle's periodic messages. Values carry a little noise from `rng`."""

    def boot_ms(t_us: int) -> int:
        return t_us // 1000 + VEHICLE_BOOT_OFFSET_MS

    def utc_us(t_us: int) -> int:
        return BASE_TIME_US + t_us + VEHICLE_UTC_OFFSET_US

    def battery_mv(t_us: int) -> int:
        return 16_420 - t_us // 40_000 - rng.randint(0, 8)

    def sys_status(mav: Any, s: VehicleState, t_us: int) -> Any:
        load = 310 + rng.randint(0, 60)
        current = 1_850 + rng.randint(0, 90) if s.armed else 42
        return mav.sys_status_encode(SENSORS_PRESENT, SENSORS_PRESENT, SENSORS_PRESENT, load,
                                     battery_mv(t_us), current, 96 - t_us // 4_000_000, 0, 0, 0, 0, 0, 0)

    def attitude(mav: Any, s: VehicleState, t_us: int) -> Any:
        moving = 1.0 if (s.vn or s.ve) else 0.0
        return mav.attitude_encode(boot_ms(t_us), rng.uniform(-0.015, 0.015),
                                   -0.09 * moving + rng.uniform(-0.01, 0.01),
                                   s.heading * DEG_TO_RAD + rng.uniform(-0.004, 0.004),
                                   rng.uniform(-0.02, 0.02), rng.uniform(-0.02, 0.02), rng.uniform(-0.01, 0.01))

    def global_position(mav: Any, s: VehicleState, t_us: int) -> Any:
        return mav.global_position_int_encode(
            boot_ms(t_us), s.lat, s.lon, round((HOME_ALT_M + s.rel_alt) * 1000), round(s.rel_alt * 1000),
            round(s.vn * 100), round(s.ve * 100), round(s.vd * 100), round(s.heading * 100) % 36_000)

    def gps_raw(mav: Any, s: VehicleState, t_us: int) -> Any:
        ground = (s.vn * s.vn + s.ve * s.ve) ** 0.5
        return mav.gps_raw_int_encode(utc_us(t_us), GPS_FIX_TYPE_3D_FIX, s.lat + rng.randint(-9, 9),
                                      s.lon + rng.randint(-9, 9),
                                      round((HOME_ALT_M + s.rel_alt) * 1000) + rng.randint(-120, 120),
                                      70 + rng.randint(0, 9), 110 + rng.randint(0, 9), round(ground * 100),
                                      round(s.heading * 100) % 36_000, 10 + rng.randint(0, 2))

    def system_time(mav: Any, s: VehicleState, t_us: int) -> Any:
        return mav.system_time_encode(utc_us(t_us), boot_ms(t_us))

    def battery(mav: Any, s: VehicleState, t_us: int) -> Any:
        cell = battery_mv(t_us) // 4
        return mav.battery_status_encode(0, 0, 1, 32_767, [cell] * 4 + [65_535] * 6,
                                         1_850 if s.armed else 42, t_us // 1_000_000 * 5, -1,
                                         96 - t_us // 4_000_000)

    def vfr_hud(mav: Any, s: VehicleState, t_us: int) -> Any:
        ground = (s.vn * s.vn + s.ve * s.ve) ** 0.5
        return mav.vfr_hud_encode(ground, ground, round(s.heading) % 360, 55 if s.armed else 0,
                                  HOME_ALT_M + s.rel_alt, -s.vd)

    table: dict[str, tuple[int, int, MessageFactory]] = {
        "HEARTBEAT": (1000, 0, _heartbeat(profile.autopilot)),
        "SYS_STATUS": (1000, 100, sys_status),
        "ATTITUDE": (100, 0, attitude),
        "GLOBAL_POSITION_INT": (200, 0, global_position),
        "GPS_RAW_INT": (1000, 300, gps_raw),
        "SYSTEM_TIME": (1000, 500, system_time),
        "BATTERY_STATUS": (2000, 700, battery),
        "VFR_HUD": (500, 200, vfr_hud),
    }
    return [Stream(name, *table[name]) for name in profile.streams]


def gcs_heartbeat(mav: Any, s: VehicleState, t_us: int) -> Any:
    """QGroundControl's heartbeat."""
    return mav.heartbeat_encode(MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID,
                                MAV_MODE_FLAG_MANUAL_INPUT_ENABLED | MAV_MODE_FLAG_SAFETY_ARMED, 0,
                                MAV_STATE_ACTIVE, 3)


def command_ack(command: int) -> MessageFactory:
    def build(mav: Any, s: VehicleState, t_us: int) -> Any:
        if isinstance(mav, mav1.MAVLink):
            return mav.command_ack_encode(command, MAV_RESULT_ACCEPTED)
        return mav.command_ack_encode(command, MAV_RESULT_ACCEPTED, 0, 0, GCS_SYSID, GCS_COMPID)
    return build


def command_long(command: int, *params: float) -> MessageFactory:
    p = list(params) + [0.0] * (7 - len(params))
    return lambda mav, s, t_us: mav.command_long_encode(VEHICLE_SYSID, VEHICLE_COMPID, command, 0, *p)


def mission_items(story: Story) -> list[MessageFactory]:
    """The 4-item mission: takeoff to 20 m, two waypoints, return to launch."""
    (n1, e1, a1), (n2, e2, a2) = story.waypoints
    home_lat, home_lon = to_degE7(0.0, 0.0)
    wp1, wp2 = to_degE7(n1, e1), to_degE7(n2, e2)
    # (command, param1 hold s, param2 acceptance radius m, x, y, z)
    rows = [
        (MAV_CMD_NAV_TAKEOFF, 0.0, 0.0, home_lat, home_lon, 20.0),
        (MAV_CMD_NAV_WAYPOINT, 0.0, 2.0, wp1[0], wp1[1], a1),
        (MAV_CMD_NAV_WAYPOINT, 5.0, 3.0, wp2[0], wp2[1], a2),
        (MAV_CMD_NAV_RETURN_TO_LAUNCH, 0.0, 0.0, 0, 0, 0.0),
    ]

    def item(seq: int, cmd: int, p1: float, p2: float, x: int, y: int, z: float) -> MessageFactory:
        p4 = NAN if cmd in (MAV_CMD_NAV_TAKEOFF, MAV_CMD_NAV_WAYPOINT) else 0.0
        return lambda mav, s, t_us: mav.mission_item_int_encode(
            VEHICLE_SYSID, VEHICLE_COMPID, seq, MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, cmd, int(seq == 0), 1,
            p1, p2, 0.0, p4, x, y, z, MAV_MISSION_TYPE_MISSION)

    return [item(i, *row) for i, row in enumerate(rows)]


def build_session(profile: Profile, story: Story, rng: Random) -> list[Send]:
    """Everything both sides send, in time order, packed by pymavlink."""
    intents: list[Intent] = []

    def plan(t: float, side: str, factories: list[MessageFactory], urgent: bool = False) -> None:
        intents.append(Intent(round(t * 1_000_000), len(intents), side, factories, urgent))

    # Periodic telemetry: a 100 ms tick; what is due at a tick goes out as separate datagrams, or
    # (as mavlink-router does) two or three of them bundled into one.
    streams = telemetry_streams(profile, rng)
    for tick in range(round(story.duration * 10)):
        t_ms = tick * 100
        due = [s.factory for s in streams if (t_ms - s.phase_ms) % s.period_ms == 0 and t_ms >= s.phase_ms]
        t = t_ms / 1000 + rng.randint(200, 3_000) / 1e6
        while due:
            n = min(len(due), rng.choice((2, 3))) if len(due) > 1 and rng.random() < profile.bundle_p else 1
            plan(t, "vehicle", due[:n])
            due = due[n:]
            t += rng.randint(30, 400) / 1e6
    for sec in range(round(story.duration)):
        plan(sec + 0.5 + rng.randint(0, 2_000) / 1e6, "gcs", [gcs_heartbeat])
    for t, severity, text in story.statustexts:
        plan(t, "vehicle", [lambda mav, s, t_us, sev=severity, txt=text: mav.statustext_encode(sev, txt.encode())])

    if story.mission_at is not None:  # MISSION_COUNT, (REQUEST_INT, ITEM_INT) x 4, MISSION_ACK
        t = story.mission_at + rng.randint(100, 900) / 1e6
        plan(t, "gcs", [lambda mav, s, t_us: mav.mission_count_encode(VEHICLE_SYSID, VEHICLE_COMPID, 4, 0)], True)
        for seq, item in enumerate(mission_items(story)):
            t += rng.randint(4_000, 12_000) / 1e6
            plan(t, "vehicle", [lambda mav, s, t_us, q=seq: mav.mission_request_int_encode(
                GCS_SYSID, GCS_COMPID, q, MAV_MISSION_TYPE_MISSION)], True)
            t += rng.randint(2_000, 9_000) / 1e6
            plan(t, "gcs", [item], True)
        t += rng.randint(4_000, 12_000) / 1e6
        plan(t, "vehicle", [lambda mav, s, t_us: mav.mission_ack_encode(
            GCS_SYSID, GCS_COMPID, MAV_MISSION_ACCEPTED, MAV_MISSION_TYPE_MISSION)], True)

    def command(at: float | None, request: MessageFactory, cmd: int) -> None:
        if at is not None:
            at += rng.randint(100, 900) / 1e6
            plan(at, "gcs", [request], True)
            plan(at + rng.randint(3_000, 15_000) / 1e6, "vehicle", [command_ack(cmd)], True)

    command(story.arm_at, command_long(MAV_CMD_COMPONENT_ARM_DISARM, 1.0), MAV_CMD_COMPONENT_ARM_DISARM)
    if story.reposition_at is not None:
        lat, lon = to_degE7(story.reposition_to[0], story.reposition_to[1])
        reposition: MessageFactory = lambda mav, s, t_us: mav.command_int_encode(  # noqa: E731
            VEHICLE_SYSID, VEHICLE_COMPID, MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, MAV_CMD_DO_REPOSITION, 0, 0,
            -1.0, 1.0, 0.0, NAN, lat, lon, story.reposition_to[2])
        command(story.reposition_at, reposition, MAV_CMD_DO_REPOSITION)
    command(story.rtl_at, command_long(MAV_CMD_NAV_RETURN_TO_LAUNCH), MAV_CMD_NAV_RETURN_TO_LAUNCH)

    # Pack in time order so that each side's sequence numbers increase along the capture.
    vehicle = Endpoint(profile.dialect, profile.vehicle_sysid, VEHICLE_COMPID,
                       link_id=VEHICLE_LINK_ID if profile.signed else None)
    gcs = Endpoint(profile.dialect, GCS_SYSID, GCS_COMPID, link_id=GCS_LINK_ID if profile.signed else None)
    sends = []
    for it in sorted(intents):
        ep = vehicle if it.side == "vehicle" else gcs
        state = vehicle_state(story, it.t_us / 1e6)
        sends.append(Send(it.t_us, it.side, [ep.pack(f(ep.mav, state, it.t_us), BASE_TIME_US + it.t_us)
                                             for f in it.factories],
                          it.urgent))
    return sends


PX4_UDP_STORY = Story(
    duration=60.0,
    keyframes=(Keyframe(0, 0, 0, 0, 90), Keyframe(17, 0, 0, 0, 90), Keyframe(22, 0, 0, 20, 45),
               Keyframe(30, 60, 60, 20, 45), Keyframe(31, 60, 60, 20, 45), Keyframe(35, 110, 10, 20, 315),
               Keyframe(36, 110, 10, 20, 315), Keyframe(40, 90, -40, 25, 250), Keyframe(44, 90, -40, 25, 250),
               Keyframe(53, 0, 0, 25, 180), Keyframe(58, 0, 0, 0, 180), Keyframe(60, 0, 0, 0, 180)),
    mission_at=5.0, arm_at=15.0, reposition_at=36.0, rtl_at=44.0, landed_at=58.5,
    statustexts=((15.2, MAV_SEVERITY_INFO, "Armed by external command"),
                 (17.3, MAV_SEVERITY_INFO, "Takeoff detected"),
                 (44.1, MAV_SEVERITY_INFO, "RTL: start return at 513 m (25 m above home)"),
                 (58.4, MAV_SEVERITY_INFO, "Landing detected"),
                 (58.6, MAV_SEVERITY_WARNING, "Disarmed by landing")),
    waypoints=((60.0, 60.0, 20.0), (110.0, 10.0, 20.0)),
    reposition_to=(90.0, -40.0, 25.0),
)

SHORT_STORY = Story(  # ~20 s: mission upload, arm, short hop, RTL
    duration=20.0,
    keyframes=(Keyframe(0, 0, 0, 0, 90), Keyframe(8, 0, 0, 0, 90), Keyframe(10, 0, 0, 10, 45),
               Keyframe(14, 20, 20, 10, 45), Keyframe(19, 0, 0, 10, 225), Keyframe(20, 0, 0, 8, 225)),
    mission_at=2.0, arm_at=7.0, rtl_at=14.0,
    statustexts=((7.2, MAV_SEVERITY_INFO, "Armed by external command"),
                 (14.1, MAV_SEVERITY_INFO, "RTL: start return")),
    waypoints=((20.0, 20.0, 10.0), (30.0, -10.0, 10.0)),
)

PX4_STREAMS = ("HEARTBEAT", "SYS_STATUS", "ATTITUDE", "GLOBAL_POSITION_INT", "GPS_RAW_INT", "SYSTEM_TIME",
               "BATTERY_STATUS", "VFR_HUD")

# --------------------------------------------------------------------------------------------------
# Packets and capture files
# --------------------------------------------------------------------------------------------------


@dataclass
class Pkt:
    """One capture record, and the MAVLink content a decoder must find in it."""

    t_ns: int  # nanoseconds since the capture start
    data: bytes
    payload_at: int = 0  # offset of the UDP/TCP payload (or of the MAVLink bytes) in data
    frames: list[tuple[int, Frame]] = field(default_factory=list)  # (payload offset, frame) in order
    cuts: list[int] = field(default_factory=list)  # payload offsets of truncated frames (noted, not counted)
    skipped: int = 0  # bytes belonging to no frame
    iface: int = 0  # pcapng interface
    cut_to: int | None = None  # write only this many bytes of data (the file ends mid-record)


def _wrap(pkt: ScapyPacket, payload: bytes, t_us: int, frames: Sequence[Frame] = (), *,
          cuts: Sequence[int] = (), skipped: int = 0, frame_offsets: Sequence[int] | None = None) -> Pkt:
    """Build a scapy packet and remember where its payload and frames are."""
    data = bytes(pkt / Raw(payload)) if payload else bytes(pkt)
    offsets = list(frame_offsets) if frame_offsets is not None else _offsets(frames)
    return Pkt(t_us * 1000, data, len(data) - len(payload), list(zip(offsets, frames)), list(cuts), skipped)


def _offsets(frames: Sequence[Frame]) -> list[int]:
    out, pos = [], 0
    for fr in frames:
        out.append(pos)
        pos += len(fr.data)
    return out


class UdpFlow:
    """Two UDP endpoints on Ethernet (zero MACs: Linux loopback) with per-sender IP ids."""

    def __init__(self, addr: dict[str, tuple[str, int]], rng: Random,
                 macs: dict[str, str] | None = None, vlan: int | None = None) -> None:
        self.addr = addr
        self.macs = macs or {side: ZERO_MAC for side in addr}
        self.vlan = vlan
        self.ip_id = {side: rng.randint(1_000, 60_000) for side in addr}

    def packet(self, send: Send) -> Pkt:
        src, dst = send.side, "gcs" if send.side == "vehicle" else "vehicle"
        self.ip_id[src] = (self.ip_id[src] + 1) % 65_536
        link = Ether(src=self.macs[src], dst=self.macs[dst])
        if self.vlan is not None:
            link = link / Dot1Q(vlan=self.vlan)
        ip = IP(src=self.addr[src][0], dst=self.addr[dst][0], id=self.ip_id[src], flags="DF", ttl=64)
        udp = UDP(sport=self.addr[src][1], dport=self.addr[dst][1])
        return _wrap(link / ip / udp, b"".join(f.data for f in send.frames), send.t_us, send.frames)


def write_pcap(path: Path, linktype: int, pkts: Sequence[Pkt]) -> list[int]:
    """Classic pcap, microsecond timestamps, little-endian. Returns the file offset of each record's data."""
    out = bytearray(struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, SNAPLEN, linktype))
    offsets = []
    for p in pkts:
        t_us = BASE_TIME_US + p.t_ns // 1000
        out += struct.pack("<IIII", t_us // 1_000_000, t_us % 1_000_000, len(p.data), len(p.data))
        offsets.append(len(out))
        out += p.data if p.cut_to is None else p.data[:p.cut_to]
    path.write_bytes(bytes(out))
    return offsets


def _pcapng_block(block_type: int, body: bytes) -> bytes:
    body += b"\0" * (-len(body) % 4)
    return struct.pack("<II", block_type, len(body) + 12) + body + struct.pack("<I", len(body) + 12)


def _pcapng_options(options: Sequence[tuple[int, bytes]]) -> bytes:
    out = b""
    for code, value in options:
        out += struct.pack("<HH", code, len(value)) + value + b"\0" * (-len(value) % 4)
    return out + struct.pack("<HH", 0, 0) if options else out


def write_pcapng(path: Path, interfaces: Sequence[tuple[int, str, int]], pkts: Sequence[Pkt]) -> list[int]:
    """pcapng: one SHB, one IDB per (linktype, name, tsresol), one EPB per packet. Returns data offsets."""
    out = bytearray(_pcapng_block(0x0A0D0D0A, struct.pack("<IHHq", 0x1A2B3C4D, 1, 0, -1) + _pcapng_options(
        [(4, b"mavscope scripts/make_captures.py")])))  # shb_userappl
    for linktype, name, tsresol in interfaces:
        opts = [(2, name.encode())] + ([(9, bytes([tsresol]))] if tsresol != 6 else [])  # if_name, if_tsresol
        out += _pcapng_block(1, struct.pack("<HHI", linktype, 0, SNAPLEN) + _pcapng_options(opts))
    offsets = []
    for p in pkts:
        tsresol = interfaces[p.iface][2]
        ts = (BASE_TIME_US * 1000 + p.t_ns) // 10 ** (9 - tsresol)
        body = struct.pack("<IIIII", p.iface, ts >> 32, ts & 0xFFFF_FFFF, len(p.data), len(p.data)) + p.data
        offsets.append(len(out) + 28)
        out += _pcapng_block(6, body)
    path.write_bytes(bytes(out))
    return offsets


# --------------------------------------------------------------------------------------------------
# Expected results
# --------------------------------------------------------------------------------------------------


def summarize(fmt: str, linktypes: list[int], records: int | None,
              located: Iterable[tuple[int | None, int, int, Frame]],
              truncated: Sequence[tuple[int | None, int]], skipped: int) -> dict[str, Any]:
    """Counts and lists from (record, index in record, file offset of STX, frame) per frame and
    (record, file offset of STX) per truncated frame."""
    rows = list(located)
    frames = [f for _, _, _, f in rows]
    return {
        "format": fmt,
        "linktypes": linktypes,
        "records": records,
        "frames": len(frames),
        "crc_ok": sum(f.crc == "ok" for f in frames),
        "crc_bad": sum(f.crc == "bad" for f in frames),
        "crc_unchecked": sum(f.crc == "unchecked" for f in frames),
        "v1": sum(f.version == 1 for f in frames),
        "v2": sum(f.version == 2 for f in frames),
        "signed": sum(f.signed for f in frames),
        "truncated": len(truncated),
        "skipped_bytes": skipped,
        "frame_list": [[rec, idx, f.sysid, f.compid, f.seq, f.msgid] for rec, idx, _, f in rows],
        "frame_offsets": [off for _, _, off, _ in rows],
        "frame_crc": [f.crc for f in frames],
        "truncated_list": [list(t) for t in truncated],
    }


def summarize_packets(fmt: str, linktypes: list[int], pkts: Sequence[Pkt], offsets: Sequence[int]) -> dict[str, Any]:
    located, cuts = [], []
    for number, (p, data_off) in enumerate(zip(pkts, offsets), start=1):
        for idx, (off, fr) in enumerate(p.frames, start=1):
            located.append((number, idx, data_off + p.payload_at + off, fr))
        cuts += [(number, data_off + p.payload_at + off) for off in p.cuts]
    return summarize(fmt, linktypes, len(pkts), located, cuts, sum(p.skipped for p in pkts))


# --------------------------------------------------------------------------------------------------
# The captures
# --------------------------------------------------------------------------------------------------


def noise_packets(t_us: int, rng: Random) -> list[Pkt]:
    """Non-MAVLink traffic a decoder must ignore: an ARP request and a DNS query to port 53."""
    arp = Ether(src="02:42:ac:11:00:02", dst="ff:ff:ff:ff:ff:ff") / ARP(
        op=1, hwsrc="02:42:ac:11:00:02", psrc="172.17.0.2", hwdst=ZERO_MAC, pdst="172.17.0.1")
    # DNS query "px4.io A" by hand: header (id, RD, one question), name, QTYPE A, QCLASS IN.
    dns = struct.pack(">HHHHHH", rng.randint(0, 65_535), 0x0100, 1, 0, 0, 0) + b"\x03px4\x02io\x00" \
        + struct.pack(">HH", 1, 1)
    query = (Ether(src=ZERO_MAC, dst=ZERO_MAC)
             / IP(src=LOOPBACK_V4, dst="127.0.0.53", id=rng.randint(1, 65_535), flags="DF", ttl=64)
             / UDP(sport=rng.randint(32_768, 60_999), dport=53))
    return [_wrap(arp, b"", t_us), _wrap(query, dns, t_us + 40_000)]


def px4_sitl_udp(outdir: Path) -> tuple[dict[str, Any], list[Send]]:
    rng = Random(1)
    profile = Profile(mav2, MAV_AUTOPILOT_PX4, PX4_STREAMS)
    sends = build_session(profile, PX4_UDP_STORY, rng)
    flow = UdpFlow({"vehicle": (LOOPBACK_V4, VEHICLE_UDP_PORT), "gcs": (LOOPBACK_V4, GCS_UDP_PORT)}, rng)
    pkts = [flow.packet(s) for s in sends]
    noise = noise_packets(12_345_678, rng) + noise_packets(47_654_321, rng)
    pkts = sorted(pkts + noise, key=lambda p: p.t_ns)  # stable: equal times keep their order
    offsets = write_pcap(outdir / "px4_sitl_udp.pcap", LINKTYPE_ETHERNET, pkts)
    summary = summarize_packets("pcap", [LINKTYPE_ETHERNET], pkts, offsets)
    summary["events"] = {"noise_records": [pkts.index(p) + 1 for p in noise]}
    return summary, sends


def px4_sitl_tlog(outdir: Path, sends: Sequence[Send]) -> dict[str, Any]:
    """QGroundControl tlog: each vehicle frame of the first 30 s, after its 8-byte big-endian µs time."""
    out, located = bytearray(), []
    for send in sends:
        if send.side != "vehicle" or send.t_us >= 30_000_000:
            continue
        for fr in send.frames:
            out += struct.pack(">Q", BASE_TIME_US + send.t_us)
            located.append((len(located) + 1, 1, len(out), fr))
            out += fr.data
    (outdir / "px4_sitl.tlog").write_bytes(bytes(out))
    return summarize("tlog", [], len(located), located, [], 0)


def serial_dump(outdir: Path, sends: Sequence[Send]) -> dict[str, Any]:
    """A raw serial stream: 10 s of vehicle frames, garbage between some, one frame cut short."""
    frames = [fr for s in sends if s.side == "vehicle" and s.t_us < 10_000_000 for fr in s.frames]
    garbage = {25: b"\x00", 80: b"\x55\xaa\x55", 150: b"\r\n", 190: b"\x00\x00\x00\x00\x07"}
    cut_index, cut_len = 110, 0
    while True:  # the first frame from #110 whose first 16 bytes hold no second start byte
        head = frames[cut_index].data[:16]
        if b"\xfd" not in head[1:] and b"\xfe" not in head[1:]:
            cut_len = 16
            break
        cut_index += 1
    out, located, skipped, cut_at = bytearray(), [], 0, 0
    for i, fr in enumerate(frames):
        if i in garbage:
            assert_no_stx(garbage[i], "serial garbage")
            out += garbage[i]
            skipped += len(garbage[i])
        if i == cut_index:
            cut_at = len(out)
            out += fr.data[:cut_len]
            # A decoder that took the next frame's bytes as this one's tail must see a bad CRC.
            assert not frame_crc_ok(fr.data[:cut_len] + frames[i + 1].data + frames[i + 2].data)
            continue
        located.append((None, len(located) + 1, len(out), fr))
        out += fr.data
    (outdir / "serial_dump.raw").write_bytes(bytes(out))
    return summarize("raw", [], None, located, [(None, cut_at)], skipped)


@dataclass
class Segment:
    """One TCP segment before it becomes a packet. `rel_seq` counts from the ISN (data starts at 1)."""

    t_us: int
    side: str
    flags: str
    rel_seq: int | None  # None: the sender's next sequence number at that moment (pure ACKs)
    payload: bytes = b""
    # Frames completing in this segment: (segment holding the STX, offset of the STX there, frame).
    frames: list[tuple[Segment, int, Frame]] = field(default_factory=list)
    options: list[tuple[str, Any]] = field(default_factory=list)


def segment_stream(sends: Iterable[Send], side: str, rng: Random, end_us: int) -> tuple[list[Segment], set[int]]:
    """Cut one side's byte stream into segments at arbitrary points: several frames per segment, some
    frames across two or three segments. Leftovers are flushed at random, always after a transaction
    reply, and always by the GCS (its writes are rare). Also returns how many segments frames span."""
    segs: list[Segment] = []
    buf, sent = b"", 1
    pending: list[list[Any]] = []  # [start in buf, end in buf, frame, segments touched, STX segment]
    spans: set[int] = set()

    def emit(n: int, t_us: int) -> None:
        nonlocal buf, pending, sent
        seg = Segment(t_us, side, "PA", sent, buf[:n])
        for p in pending:
            p[3] += p[0] < n
            if 0 <= p[0] < n:
                p[4] = seg
            if p[1] <= n:
                seg.frames.append((p[4], p[0] + seg.rel_seq - p[4].rel_seq, p[2]))
                spans.add(p[3])
        pending = [[a - n, b - n, f, k, first] for a, b, f, k, first in pending if b > n]
        buf, sent = buf[n:], sent + n
        segs.append(seg)

    for send in sends:
        for fr in send.frames:
            pending.append([len(buf), len(buf) + len(fr.data), fr, 0, None])
            buf += fr.data
        t = send.t_us
        while True:
            size = rng.randint(5, 24) if rng.random() < 0.1 else rng.randint(48, 300)
            if len(buf) < size:
                break
            emit(size, t)
            t += rng.randint(8, 40)
        if buf and (send.urgent or side == "gcs" or rng.random() < 0.4):
            emit(len(buf), t)
    if buf:
        emit(len(buf), end_us)
    return segs, spans


def px4_sitl_tcp(outdir: Path) -> dict[str, Any]:
    """The SHORT_STORY session over one TCP connection from the GCS to the vehicle at 127.0.0.1:5760."""
    rng = Random(2)
    sends = build_session(Profile(mav2, MAV_AUTOPILOT_PX4, PX4_STREAMS), SHORT_STORY, rng)
    port = {"vehicle": ARDUPILOT_TCP_PORT, "gcs": GCS_TCP_PORT}
    peer = {"vehicle": "gcs", "gcs": "vehicle"}
    isn = {"vehicle": rng.getrandbits(32), "gcs": rng.getrandbits(32)}
    end_us = round(SHORT_STORY.duration * 1e6)

    syn_opts = [("MSS", 65_495), ("SAckOK", b""), ("NOP", None), ("WScale", 7)]
    handshake = [Segment(0, "gcs", "S", 0, options=syn_opts), Segment(45, "vehicle", "SA", 0, options=syn_opts),
                 Segment(80, "gcs", "A", 1)]
    vehicle_segs, vehicle_spans = segment_stream((s for s in sends if s.side == "vehicle"), "vehicle", rng, end_us)
    gcs_segs, gcs_spans = segment_stream((s for s in sends if s.side == "gcs"), "gcs", rng, end_us)
    if not {2, 3} <= vehicle_spans | gcs_spans:
        raise AssertionError("the TCP capture must hold frames split across 2 and across 3 segments")
    data = sorted(vehicle_segs + gcs_segs, key=lambda s: s.t_us)

    # Delayed ACKs: every second data segment from the vehicle, every one from the GCS.
    segs, unacked = list(handshake), 0
    for s in data:
        segs.append(s)
        unacked = unacked + 1 if s.side == "vehicle" else 2
        if unacked >= 2:
            segs.append(Segment(s.t_us + rng.randint(20, 60), peer[s.side], "A", None))
            unacked = 0
    segs.sort(key=lambda s: s.t_us)

    # One spurious retransmission (an exact copy, 210 ms later: the minimum RTO) ...
    orig = next(s for s in segs if s.side == "vehicle" and s.payload and s.t_us >= 6_000_000)
    retransmission = Segment(orig.t_us + 210_000, "vehicle", "PA", orig.rel_seq, orig.payload)
    segs.append(retransmission)
    segs.sort(key=lambda s: s.t_us)
    # ... and one pair of adjacent vehicle segments recorded in the wrong order.
    a = next(i for i, s in enumerate(segs) if s.t_us >= 11_000_000 and all(
        x.side == "vehicle" and x.frames for x in segs[i:i + 2]))
    segs[a], segs[a + 1] = segs[a + 1], segs[a]
    swapped = segs[a:a + 2]
    segs[a].t_us, segs[a + 1].t_us = segs[a + 1].t_us, segs[a].t_us

    # Close: the GCS sends FIN, the vehicle acknowledges it and closes too.
    nxt = {side: max(s.rel_seq + len(s.payload) for s in data if s.side == side) for side in peer}
    end = end_us + 150_000
    segs += [Segment(end, "gcs", "FA", nxt["gcs"]), Segment(end + 40, "vehicle", "A", nxt["vehicle"]),
             Segment(end + 300, "vehicle", "FA", nxt["vehicle"]), Segment(end + 340, "gcs", "A", nxt["gcs"] + 1)]

    # Sequence and acknowledgement numbers: on loopback whatever was sent before has arrived.
    sent_to = {"vehicle": 1, "gcs": 1}  # relative sequence number after the last byte (or SYN/FIN) sent
    ip_id = {side: rng.randint(1_000, 60_000) for side in peer}
    last_ack = {"vehicle": -1, "gcs": -1}
    pkts: list[Pkt] = []
    record_of: dict[int, int] = {}  # id(segment) -> record number
    for s in segs:
        other = peer[s.side]
        rel_seq = sent_to[s.side] if s.rel_seq is None else s.rel_seq
        sent_to[s.side] = max(sent_to[s.side], rel_seq + len(s.payload) + ("F" in s.flags))
        ack = (isn[other] + sent_to[other]) % 2**32 if "A" in s.flags else 0
        if s.rel_seq is None and ack == last_ack[s.side]:
            continue  # a reply already acknowledged this: no duplicate ACK
        last_ack[s.side] = ack
        ip_id[s.side] = (ip_id[s.side] + 1) % 65_536
        tcp = TCP(sport=port[s.side], dport=port[other], seq=(isn[s.side] + rel_seq) % 2**32, ack=ack,
                  flags=s.flags, window=SYN_WINDOW.get(s.flags, 512), options=s.options)
        ip = IP(src=LOOPBACK_V4, dst=LOOPBACK_V4, id=ip_id[s.side], flags="DF", ttl=64)
        pkts.append(_wrap(Ether(src=ZERO_MAC, dst=ZERO_MAC) / ip / tcp, s.payload, s.t_us))
        record_of.setdefault(id(s), len(pkts))
    offsets = write_pcap(outdir / "px4_sitl_tcp.pcap", LINKTYPE_ETHERNET, pkts)

    # A frame completes in the record that makes the stream contiguous up to its last byte: for the
    # out-of-order pair, the later record (as Wireshark shows a reassembled PDU).
    completed: dict[int, list[tuple[int | None, Frame]]] = {}
    for side_segs in (vehicle_segs, gcs_segs):
        latest = 0
        for s in side_segs:  # in stream order
            latest = max(latest, record_of[id(s)])
            for first, off, fr in s.frames:
                rec = record_of[id(first)]
                completed.setdefault(latest, []).append((offsets[rec - 1] + pkts[rec - 1].payload_at + off, fr))
    located = [(rec, idx, off, fr) for rec in sorted(completed)
               for idx, (off, fr) in enumerate(completed[rec], start=1)]
    summary = summarize("pcap", [LINKTYPE_ETHERNET], len(pkts), located, [], 0)
    summary["events"] = {"retransmission": [record_of[id(orig)], record_of[id(retransmission)]],
                         "out_of_order": [record_of[id(x)] for x in swapped]}
    return summary


def mavlink_v1_udp(outdir: Path) -> dict[str, Any]:
    rng = Random(3)
    story = Story(duration=20.0, keyframes=(Keyframe(0, 0, 0, 0, 0), Keyframe(20, 0, 0, 0, 0)), arm_at=8.0)
    profile = Profile(mav1, MAV_AUTOPILOT_ARDUPILOTMEGA, ("HEARTBEAT", "SYS_STATUS", "ATTITUDE", "GPS_RAW_INT"),
                      bundle_p=0.0)
    sends = build_session(profile, story, rng)
    flow = UdpFlow({"vehicle": (LOOPBACK_V4, VEHICLE_UDP_PORT), "gcs": (LOOPBACK_V4, GCS_UDP_PORT)}, rng)
    pkts = [flow.packet(s) for s in sends]
    offsets = write_pcap(outdir / "mavlink_v1_udp.pcap", LINKTYPE_ETHERNET, pkts)
    return summarize_packets("pcap", [LINKTYPE_ETHERNET], pkts, offsets)


def signed_udp(outdir: Path) -> dict[str, Any]:
    rng = Random(4)
    story = Story(duration=20.0, keyframes=(Keyframe(0, 0, 0, 0, 0), Keyframe(5, 0, 0, 0, 0),
                                            Keyframe(8, 0, 0, 15, 0), Keyframe(13, 30, 0, 15, 0),
                                            Keyframe(19, 0, 0, 15, 180), Keyframe(20, 0, 0, 12, 180)),
                  arm_at=4.0, rtl_at=13.0)
    profile = Profile(mav2, MAV_AUTOPILOT_PX4, ("HEARTBEAT", "SYS_STATUS", "ATTITUDE", "GLOBAL_POSITION_INT"),
                      signed=True)
    sends = build_session(profile, story, rng)
    flow = UdpFlow({"vehicle": (LOOPBACK_V4, VEHICLE_UDP_PORT), "gcs": (LOOPBACK_V4, GCS_UDP_PORT)}, rng)
    pkts = [flow.packet(s) for s in sends]
    offsets = write_pcap(outdir / "signed_udp.pcap", LINKTYPE_ETHERNET, pkts)
    return summarize_packets("pcap", [LINKTYPE_ETHERNET], pkts, offsets)


@dataclass(frozen=True)
class DamageCase:
    record: int
    what: str
    expect: str


@dataclass(frozen=True)
class Junk:
    """Bytes in a datagram that belong to no frame."""

    data: bytes


@dataclass(frozen=True)
class Cut:
    """The first bytes of a frame whose rest is missing."""

    data: bytes


def damaged(outdir: Path) -> tuple[dict[str, Any], list[DamageCase]]:
    """A short UDP capture, one error case per datagram (each documented in README.md)."""
    vehicle = Endpoint(mav2, VEHICLE_SYSID, VEHICLE_COMPID)
    m = vehicle.mav
    state = vehicle_state(PX4_UDP_STORY, 0.0)
    pkts: list[Pkt] = []
    cases: list[DamageCase] = []

    def now() -> int:
        return len(pkts) * 250_000

    def heartbeat() -> Frame:
        return vehicle.pack(_heartbeat(MAV_AUTOPILOT_PX4)(m, state, now()), now())

    def attitude(roll: float) -> Frame:
        return vehicle.pack(m.attitude_encode(VEHICLE_BOOT_OFFSET_MS + now() // 1000, roll, 0.01, 1.5,
                                              0.002, 0.001, 0.0), now())

    def datagram(parts: Sequence[Frame | Junk | Cut], what: str, expect: str, cut_to: int | None = None) -> None:
        frames, offsets, cuts, junk_at, payload = [], [], [], [], b""
        for part in parts:
            if isinstance(part, Frame):
                frames.append(part)
                offsets.append(len(payload))
            elif isinstance(part, Cut):
                cuts.append(len(payload))
            else:
                junk_at += range(len(payload), len(payload) + len(part.data))
            payload += part.data
        for i in (i for i in junk_at if payload[i] in (0xFD, 0xFE)):
            # a stray start byte must not begin a complete frame: its claimed length runs past the end
            assert i + 2 >= len(payload) or i + payload[i + 1] + (12 if payload[i] == 0xFD else 8) > len(payload)
        udp = (Ether(src=ZERO_MAC, dst=ZERO_MAC)
               / IP(src=LOOPBACK_V4, dst=LOOPBACK_V4, id=31_000 + len(pkts), flags="DF", ttl=64)
               / UDP(sport=VEHICLE_UDP_PORT, dport=GCS_UDP_PORT))
        pkt = _wrap(udp, payload, now(), frames, frame_offsets=offsets,
                    cuts=cuts,
                    skipped=sum(len(p.data) for p in parts if isinstance(p, Junk)))
        pkt.cut_to = cut_to
        pkts.append(pkt)
        cases.append(DamageCase(len(pkts), what, expect))

    datagram([heartbeat()], "a clean HEARTBEAT (baseline)", "1 frame, CRC ok")

    junk = b"\x00\x13\x37junk\x00"
    assert_no_stx(junk, "garbage prefix")
    datagram([Junk(junk), attitude(0.01)], f"{len(junk)} garbage bytes, then an ATTITUDE frame",
             f"skipped-bytes ({len(junk)} bytes), then 1 frame, CRC ok")

    fr = vehicle.pack(m.sys_status_encode(SENSORS_PRESENT, SENSORS_PRESENT, SENSORS_PRESENT, 350, 16_300, 42,
                                          95, 0, 0, 0, 0, 0, 0), now())
    flipped = bytearray(fr.data)
    flipped[10 + 4] ^= 0x01  # a payload byte
    assert_no_stx(bytes(flipped[1:]), "bad-CRC SYS_STATUS")
    datagram([Frame(bytes(flipped), fr.sysid, fr.compid, fr.seq, fr.msgid, 2, crc="bad")],
             "SYS_STATUS with one bit of payload byte 4 flipped", "1 frame, bad-crc")

    hb, att = heartbeat(), attitude(0.02)
    cut = att.data[:21]
    assert_no_stx(cut[1:], "truncated ATTITUDE")
    datagram([hb, Cut(cut)], f"HEARTBEAT, then an ATTITUDE frame cut after {len(cut)} of its {len(att.data)} bytes",
             "1 frame, CRC ok; then truncated-frame (not counted as a frame)")

    gpi = vehicle.pack(m.global_position_int_encode(VEHICLE_BOOT_OFFSET_MS + now() // 1000, state.lat, state.lon,
                                                    488_000, 0, 0, 0, 0, 9_000), now())
    att = attitude(0.03)
    bad = bytearray(att.data)
    bad[-1] ^= 0x5A  # the CRC's high byte
    assert_no_stx(bytes(bad[1:]), "bad-CRC ATTITUDE")
    datagram([gpi, Frame(bytes(bad), att.sysid, att.compid, att.seq, att.msgid, 2, crc="bad")],
             "two frames: GLOBAL_POSITION_INT, then an ATTITUDE whose CRC field is wrong",
             "2 frames: the first CRC ok, the second bad-crc")

    seq = vehicle.next_seq()
    unknown = v2_frame(UNKNOWN_MSGID, bytes(range(1, 11)), seq, VEHICLE_SYSID, VEHICLE_COMPID, 0)
    datagram([Frame(unknown, VEHICLE_SYSID, VEHICLE_COMPID, seq, UNKNOWN_MSGID, 2, crc="unchecked")],
             f"message id {UNKNOWN_MSGID} (in no dialect), 10-byte payload, CRC made with CRC_EXTRA 0",
             "1 frame, CRC unchecked, unknown-msgid")

    hb = heartbeat()
    flagged = v2_frame(hb.msgid, hb.data[10:-2], hb.seq, hb.sysid, hb.compid,
                       mav2.MAVLink_heartbeat_message.crc_extra, incompat=UNKNOWN_INCOMPAT_FLAG)
    datagram([Frame(flagged, hb.sysid, hb.compid, hb.seq, hb.msgid, 2)],
             f"HEARTBEAT with incompat flag 0x{UNKNOWN_INCOMPAT_FLAG:02x} set (CRC valid over the flagged header)",
             "1 frame, CRC ok, unknown-incompat-flags (pymavlink and the C library drop it)")

    datagram([Junk(b"\xfe\xfd"), heartbeat(), Junk(b"\xfd\xfe\xfd"), attitude(0.04)],
             "stray bytes fe fd, a HEARTBEAT, stray bytes fd fe fd, an ATTITUDE",
             "2 frames, CRC ok; the 5 stray bytes are skipped-bytes (each would-be frame they start claims a "
             "length that runs past the datagram, and a valid frame starts inside it)")

    hb = heartbeat()
    headers = 14 + 20 + 8
    cut_to = headers + 8
    datagram([Cut(hb.data)],
             f"a HEARTBEAT in the last record; the file ends {cut_to} bytes into the record's {headers + len(hb.data)}",
             f"record-truncated; the UDP payload ends after 8 of the frame's {len(hb.data)} bytes: "
             "truncated-frame, no frame", cut_to=cut_to)

    offsets = write_pcap(outdir / "damaged.pcap", LINKTYPE_ETHERNET, pkts)
    return summarize_packets("pcap", [LINKTYPE_ETHERNET], pkts, offsets), cases


def px4_sitl_sll2(outdir: Path) -> dict[str, Any]:
    """pcapng, two interfaces: SLL2 + IPv6 loopback (µs), Ethernet + 802.1Q VLAN + IPv4 (ns)."""
    rng = Random(6)
    story = Story(duration=10.0, keyframes=(Keyframe(0, 0, 0, 10, 0), Keyframe(10, 30, 0, 10, 0)))
    streams = ("HEARTBEAT", "SYS_STATUS", "ATTITUDE", "GLOBAL_POSITION_INT")
    pkts: list[Pkt] = []

    # Interface 0: `tcpdump -i any` on Linux (SLL2) sees the SITL vehicle talk to QGC over [::1].
    flow_label = rng.getrandbits(20)
    for send in build_session(Profile(mav2, MAV_AUTOPILOT_PX4, streams), story, rng):
        sport, dport = (VEHICLE_UDP_PORT, GCS_UDP_PORT) if send.side == "vehicle" else (GCS_UDP_PORT, VEHICLE_UDP_PORT)
        payload = b"".join(f.data for f in send.frames)
        ip6 = bytes(IPv6(src="::1", dst="::1", hlim=64, fl=flow_label) / UDP(sport=sport, dport=dport) / Raw(payload))
        # SLL2: protocol, reserved, ifindex (1 = lo), ARPHRD_LOOPBACK, PACKET_HOST, addr len, addr (8)
        sll2 = struct.pack(">HHIHBB8s", 0x86DD, 0, 1, 772, 0, 6, b"")
        pkts.append(Pkt(send.t_us * 1000, sll2 + ip6, len(sll2) + len(ip6) - len(payload),
                        list(zip(_offsets(send.frames), send.frames)), iface=0))

    # Interface 1: a second vehicle (sysid 2) on a lab network, VLAN 10, timestamps in nanoseconds.
    flow = UdpFlow({"vehicle": ("192.168.10.2", 14555), "gcs": ("192.168.10.1", GCS_UDP_PORT)}, rng,
                   macs={"vehicle": "02:00:00:0a:00:02", "gcs": "02:00:00:0a:00:01"}, vlan=10)
    for send in build_session(Profile(mav2, MAV_AUTOPILOT_PX4, streams, vehicle_sysid=2), story, rng):
        pkt = flow.packet(send)
        pkt.t_ns += rng.randint(0, 999)
        pkt.iface = 1
        pkts.append(pkt)

    pkts.sort(key=lambda p: p.t_ns)
    interfaces = [(LINKTYPE_LINUX_SLL2, "any", 6), (LINKTYPE_ETHERNET, "eth0", 9)]
    offsets = write_pcapng(outdir / "px4_sitl_sll2.pcapng", interfaces, pkts)
    return summarize_packets("pcapng", [LINKTYPE_LINUX_SLL2, LINKTYPE_ETHERNET], pkts, offsets)


# --------------------------------------------------------------------------------------------------
# Captures with a known analysis truth: loss, mission transfers, commands, clocks (docs/analysis.md)
# --------------------------------------------------------------------------------------------------

ROGUE_SYSID, ROGUE_COMPID, ROGUE_UDP_PORT = 66, 190, 14_551
MAV_RESULT_DENIED, MAV_RESULT_FAILED = 2, 4
MAV_CMD_DO_SET_MODE, MAV_CMD_REQUEST_MESSAGE = 176, 512
MAV_MISSION_TYPE_FENCE, MAV_MISSION_UNSUPPORTED = 1, 3
MAV_CMD_NAV_LAND = 21
SKEW_OFFSET_US = 2_500_000  # clock_skew.pcap: the vehicle's UTC clock is 2.5 s ahead at capture start...
SKEW_DRIFT_PPM = 250  # ...and gains 250 µs per second
SKEW_BOOT_US = 123_456_789  # the vehicle booted this long (by its own clock) before the capture starts

Script = list[tuple[int, str, Callable[[Any], Any]]]  # (t_us, side, mav -> message)


def pack_script(script: Script, endpoints: dict[str, Endpoint],
                sign_time: Callable[[str, int], int] | None = None) -> list[Send]:
    """Pack scripted messages in time order, one datagram each (sequence numbers follow the time order)."""
    sends = []
    for t_us, side, build in sorted(script, key=lambda e: e[0]):
        ep = endpoints[side]
        at = sign_time(side, t_us) if sign_time is not None else BASE_TIME_US + t_us
        sends.append(Send(t_us, side, [ep.pack(build(ep.mav), at)]))
    return sends


def heartbeats(script: Script, duration_s: int, sides: Sequence[str] = ("vehicle", "gcs")) -> None:
    quad = _heartbeat(MAV_AUTOPILOT_PX4)
    state = vehicle_state(SHORT_STORY, 0.0)
    for sec in range(duration_s):
        if "vehicle" in sides:
            script.append((sec * 1_000_000 + 1_000, "vehicle", lambda mav: quad(mav, state, 0)))
        if "gcs" in sides:
            script.append((sec * 1_000_000 + 500_000, "gcs", lambda mav: gcs_heartbeat(mav, state, 0)))


def stats_loss(outdir: Path) -> dict[str, Any]:
    """A 30 s session, one frame per datagram, with known datagrams removed, one duplicated and three
    vehicle frames corrupted: the loss per link is known."""
    rng = Random(11)
    story = Story(duration=30.0, keyframes=(Keyframe(0, 0, 0, 0, 90), Keyframe(30, 0, 0, 0, 90)))
    profile = Profile(mav2, MAV_AUTOPILOT_PX4, ("HEARTBEAT", "SYS_STATUS", "ATTITUDE", "GLOBAL_POSITION_INT"),
                      bundle_p=0.0)
    sends = build_session(profile, story, rng)
    vehicle = [s for s in sends if s.side == "vehicle"]
    gcs = [s for s in sends if s.side == "gcs"]
    drop = {id(vehicle[i]) for i in (50, 120, 121, 122, *range(300, 340))} | {id(gcs[10]), id(gcs[20])}
    duplicate = vehicle[200]
    corrupt = [s for s in vehicle[400:] if not any(b in (0xFD, 0xFE) for b in s.frames[0].data[1:])][:3]
    flow = UdpFlow({"vehicle": (LOOPBACK_V4, VEHICLE_UDP_PORT), "gcs": (LOOPBACK_V4, GCS_UDP_PORT)}, rng)
    pkts = []
    for s in sends:
        if id(s) in drop:
            continue
        if any(s is c for c in corrupt):
            fr = s.frames[0]
            bad = bytearray(fr.data)
            bad[10] ^= 0x01  # the first payload byte: header (and so seq) intact, CRC wrong
            s = Send(s.t_us, s.side, [Frame(bytes(bad), fr.sysid, fr.compid, fr.seq, fr.msgid, 2, crc="bad")])
        pkts.append(flow.packet(s))
        if s is duplicate:  # the same datagram delivered twice (a duplicate, not a loss)
            pkts.append(flow.packet(Send(s.t_us + 250, s.side, s.frames)))
    offsets = write_pcap(outdir / "stats_loss.pcap", LINKTYPE_ETHERNET, pkts)
    summary = summarize_packets("pcap", [LINKTYPE_ETHERNET], pkts, offsets)
    n_vehicle = sum(len(s.frames) for s in vehicle)
    summary["truth"] = {
        "links": {
            f"{VEHICLE_SYSID}/{VEHICLE_COMPID}": {"sent": n_vehicle, "received": n_vehicle - 44 + 1, "lost": 44,
                                                 "duplicates": 1, "crc_bad": 3},
            f"{GCS_SYSID}/{GCS_COMPID}": {"sent": len(gcs), "received": len(gcs) - 2, "lost": 2, "duplicates": 0,
                                         "crc_bad": 0},
        },
        "removed_vehicle_frames": "indices 50, 120-122 and 300-339 of the vehicle's frames (44)",
        "removed_gcs_frames": "heartbeats 10 and 20",
    }
    return summary


def mission_item(seq: int, cmd: int, x: int, y: int, z: float, p1: float = 0.0, p2: float = 0.0,
                 target: tuple[int, int] = (VEHICLE_SYSID, VEHICLE_COMPID),
                 mission_type: int = MAV_MISSION_TYPE_MISSION) -> Callable[[Any], Any]:
    return lambda mav: mav.mission_item_int_encode(target[0], target[1], seq, MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                                                   cmd, int(seq == 0), 1, p1, p2, 0.0, NAN if cmd == 16 else 0.0,
                                                   x, y, z, mission_type)


def mission_resend(outdir: Path) -> dict[str, Any]:
    """Four mission transfers: a download, an upload with a re-requested (resent) item, a fence upload
    the vehicle refuses, and an upload abandoned after its first item."""
    rng = Random(12)
    script: Script = []
    heartbeats(script, 20)
    home = to_degE7(0.0, 0.0)
    wp = [to_degE7(40.0, 0.0), to_degE7(40.0, 40.0), to_degE7(0.0, 40.0)]
    gcs_t, veh_t = (GCS_SYSID, GCS_COMPID), (VEHICLE_SYSID, VEHICLE_COMPID)
    t = 1_200_000

    def at(side: str, build: Callable[[Any], Any], gap_us: int) -> None:
        nonlocal t
        t += gap_us + rng.randint(0, 999)
        script.append((t, side, build))

    # 1. download: the vehicle's current 2-item mission
    at("gcs", lambda mav: mav.mission_request_list_encode(*veh_t, MAV_MISSION_TYPE_MISSION), 0)
    at("vehicle", lambda mav: mav.mission_count_encode(*gcs_t, 2, MAV_MISSION_TYPE_MISSION), 6_000)
    old = [mission_item(0, MAV_CMD_NAV_TAKEOFF, *home, 15.0, target=gcs_t),
           mission_item(1, MAV_CMD_NAV_LAND, *home, 0.0, target=gcs_t)]
    for seq in range(2):
        at("gcs", lambda mav, q=seq: mav.mission_request_int_encode(*veh_t, q, MAV_MISSION_TYPE_MISSION), 5_000)
        at("vehicle", old[seq], 6_000)
    at("gcs", lambda mav: mav.mission_ack_encode(*veh_t, MAV_MISSION_ACCEPTED, MAV_MISSION_TYPE_MISSION), 5_000)

    # 2. upload of 4 items; the vehicle asks for item 2 again (the first copy "timed out")
    t = 5_000_000
    new = [mission_item(0, MAV_CMD_NAV_TAKEOFF, *home, 25.0),
           mission_item(1, MAV_CMD_NAV_WAYPOINT, *wp[0], 25.0, p2=2.0),
           mission_item(2, MAV_CMD_NAV_WAYPOINT, *wp[1], 30.0, p1=5.0, p2=2.0),
           mission_item(3, MAV_CMD_NAV_WAYPOINT, *wp[2], 25.0, p2=2.0)]
    at("gcs", lambda mav: mav.mission_count_encode(*veh_t, 4, MAV_MISSION_TYPE_MISSION), 0)
    for seq, wait_us in ((0, 6_000), (1, 6_000), (2, 6_000), (2, 1_500_000), (3, 6_000)):  # 2 asked twice
        at("vehicle", lambda mav, q=seq: mav.mission_request_int_encode(*gcs_t, q, MAV_MISSION_TYPE_MISSION),
           wait_us)
        at("gcs", new[seq], 5_000)
    at("vehicle", lambda mav: mav.mission_ack_encode(*gcs_t, MAV_MISSION_ACCEPTED, MAV_MISSION_TYPE_MISSION), 6_000)

    # 3. a fence upload the vehicle does not support
    t = 9_000_000
    at("gcs", lambda mav: mav.mission_count_encode(*veh_t, 1, MAV_MISSION_TYPE_FENCE), 0)
    at("vehicle", lambda mav: mav.mission_ack_encode(*gcs_t, MAV_MISSION_UNSUPPORTED, MAV_MISSION_TYPE_FENCE), 7_000)

    # 4. an upload of 3 items abandoned after item 0 (the GCS goes silent about it)
    t = 12_000_000
    at("gcs", lambda mav: mav.mission_count_encode(*veh_t, 3, MAV_MISSION_TYPE_MISSION), 0)
    at("vehicle", lambda mav: mav.mission_request_int_encode(*gcs_t, 0, MAV_MISSION_TYPE_MISSION), 6_000)
    at("gcs", mission_item(0, MAV_CMD_NAV_TAKEOFF, *home, 40.0), 5_000)
    at("vehicle", lambda mav: mav.mission_request_int_encode(*gcs_t, 1, MAV_MISSION_TYPE_MISSION), 6_000)

    endpoints = {"vehicle": Endpoint(mav2, *veh_t), "gcs": Endpoint(mav2, *gcs_t)}
    sends = pack_script(script, endpoints)
    flow = UdpFlow({"vehicle": (LOOPBACK_V4, VEHICLE_UDP_PORT), "gcs": (LOOPBACK_V4, GCS_UDP_PORT)}, rng)
    pkts = [flow.packet(s) for s in sends]
    offsets = write_pcap(outdir / "mission_resend.pcap", LINKTYPE_ETHERNET, pkts)
    summary = summarize_packets("pcap", [LINKTYPE_ETHERNET], pkts, offsets)
    summary["truth"] = {"transfers": [
        {"from": [1, 1], "to": [255, 190], "direction": "download", "mission_type": "MAV_MISSION_TYPE_MISSION",
         "count": 2, "complete": True, "commands": [22, 21]},
        {"from": [255, 190], "to": [1, 1], "direction": "upload", "mission_type": "MAV_MISSION_TYPE_MISSION",
         "count": 4, "complete": True, "commands": [22, 16, 16, 16], "resent": [2],
         "degrees": [[a / 1e7, b / 1e7] for a, b in [home] + wp]},
        {"from": [255, 190], "to": [1, 1], "direction": "upload", "mission_type": "MAV_MISSION_TYPE_FENCE",
         "count": 1, "complete": False, "result": "MAV_MISSION_UNSUPPORTED"},
        {"from": [255, 190], "to": [1, 1], "direction": "upload", "mission_type": "MAV_MISSION_TYPE_MISSION",
         "count": 3, "complete": False, "items_received": 1, "reason": "abandoned"},
    ]}
    return summary


def commands_ack(outdir: Path) -> dict[str, Any]:
    """Commands from the GCS with their ACKs: accepted, denied, failed, a retry, one unanswered; then a
    command from a new system id on another port, and a byte-for-byte replay of the arm command."""
    rng = Random(13)
    script: Script = []
    heartbeats(script, 30)
    veh = (VEHICLE_SYSID, VEHICLE_COMPID)
    truth: list[dict[str, Any]] = []

    def long(cmd: int, *params: float, confirmation: int = 0) -> Callable[[Any], Any]:
        p = list(params) + [0.0] * (7 - len(params))
        return lambda mav: mav.command_long_encode(*veh, cmd, confirmation, *p)

    def ack(cmd: int, result: int, to: tuple[int, int] = (GCS_SYSID, GCS_COMPID)) -> Callable[[Any], Any]:
        return lambda mav: mav.command_ack_encode(cmd, result, 0, 0, *to)

    def exchange(t_us: int, cmd: int, request: Callable[[Any], Any], result: int | None, latency_us: int = 0,
                 retries: Sequence[tuple[int, Callable[[Any], Any]]] = (), side: str = "gcs",
                 kind: str = "COMMAND_LONG") -> None:
        script.append((t_us, side, request))
        for after_us, again in retries:  # the same command again (COMMAND_LONG: confirmation + 1)
            script.append((t_us + after_us, side, again))
        if result is not None:
            to = (GCS_SYSID, GCS_COMPID) if side == "gcs" else (ROGUE_SYSID, ROGUE_COMPID)
            script.append((t_us + latency_us, "vehicle", ack(cmd, result, to)))
        truth.append({"command": cmd, "kind": kind, "from": side, "result": result, "retries": len(retries),
                      "latency_ms": latency_us / 1000 if result is not None else None})

    exchange(2_000_000, MAV_CMD_COMPONENT_ARM_DISARM, long(MAV_CMD_COMPONENT_ARM_DISARM, 1.0),
             MAV_RESULT_ACCEPTED, 12_345)
    exchange(4_000_000, MAV_CMD_NAV_TAKEOFF, long(MAV_CMD_NAV_TAKEOFF, 0, 0, 0, NAN, NAN, NAN, 500.0),
             MAV_RESULT_DENIED, 8_250)
    exchange(6_000_000, MAV_CMD_DO_SET_MODE, long(MAV_CMD_DO_SET_MODE, 1.0, 4.0),  # first copy unanswered
             MAV_RESULT_ACCEPTED, 1_509_000,
             retries=((1_500_000, long(MAV_CMD_DO_SET_MODE, 1.0, 4.0, confirmation=1)),))
    lat, lon = to_degE7(30.0, 30.0)
    exchange(9_000_000, MAV_CMD_DO_REPOSITION,
             lambda mav: mav.command_int_encode(*veh, MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, MAV_CMD_DO_REPOSITION, 0,
                                                0, -1.0, 1.0, 0.0, NAN, lat, lon, 20.0),
             MAV_RESULT_FAILED, 21_000, kind="COMMAND_INT")
    exchange(12_000_000, MAV_CMD_REQUEST_MESSAGE, long(MAV_CMD_REQUEST_MESSAGE, 148.0), None)
    exchange(15_000_000, MAV_CMD_NAV_RETURN_TO_LAUNCH, long(MAV_CMD_NAV_RETURN_TO_LAUNCH), MAV_RESULT_ACCEPTED, 5_500)
    # a system never seen before commands the vehicle from another UDP port: disarm (force)
    exchange(20_000_000, MAV_CMD_COMPONENT_ARM_DISARM, long(MAV_CMD_COMPONENT_ARM_DISARM, 0.0, 21196.0),
             MAV_RESULT_ACCEPTED, 9_000, side="rogue")
    # the setup of message signing, key in clear
    script.append((24_000_000, "gcs", lambda mav: mav.setup_signing_encode(*veh, bytes(range(32)), 0)))

    endpoints = {"vehicle": Endpoint(mav2, *veh), "gcs": Endpoint(mav2, GCS_SYSID, GCS_COMPID),
                 "rogue": Endpoint(mav2, ROGUE_SYSID, ROGUE_COMPID)}
    sends = pack_script(script, endpoints)
    flow = UdpFlow({"vehicle": (LOOPBACK_V4, VEHICLE_UDP_PORT), "gcs": (LOOPBACK_V4, GCS_UDP_PORT)}, rng)
    rogue = UdpFlow({"vehicle": (LOOPBACK_V4, VEHICLE_UDP_PORT), "gcs": (LOOPBACK_V4, ROGUE_UDP_PORT)}, rng)
    pkts = []
    for s in sends:
        if s.side == "rogue":
            pkts.append(rogue.packet(Send(s.t_us, "gcs", s.frames)))
        elif s.side == "vehicle" and s.frames[0].msgid == 77 and s.t_us >= 20_000_000:
            pkts.append(rogue.packet(s))  # the ACK to the rogue goes to its port
        else:
            pkts.append(flow.packet(s))
    arm = next(s for s in sends if s.side == "gcs" and s.frames[0].msgid == 76)
    replay_at = 26_000_000
    replay = flow.packet(Send(replay_at, "gcs", arm.frames))  # the captured arm command, sent again as is
    pkts = sorted(pkts + [replay], key=lambda p: p.t_ns)
    offsets = write_pcap(outdir / "commands_ack.pcap", LINKTYPE_ETHERNET, pkts)
    summary = summarize_packets("pcap", [LINKTYPE_ETHERNET], pkts, offsets)
    original = next(i for i, p in enumerate(pkts, 1) if p.frames and p.frames[0][1] is arm.frames[0])
    truth.append({"command": MAV_CMD_COMPONENT_ARM_DISARM, "kind": "COMMAND_LONG", "from": "gcs", "result": None,
                  "retries": 0, "latency_ms": None, "replay_of_record": original})
    summary["truth"] = {"commands": truth, "replay_record": pkts.index(replay) + 1,
                        "rogue": [ROGUE_SYSID, ROGUE_COMPID, ROGUE_UDP_PORT],
                        "setup_signing_record": next(i for i, p in enumerate(pkts, 1)
                                                     if p.frames and p.frames[0][1].msgid == 256)}
    return summary


def clock_skew(outdir: Path) -> dict[str, Any]:
    """60 s in which the vehicle's clock is SKEW_OFFSET_US ahead and gains SKEW_DRIFT_PPM: SYSTEM_TIME,
    signature timestamps (vehicle frames signed), ATTITUDE time_boot_ms, TIMESYNC and PING exchanges."""
    rng = Random(14)
    script: Script = []
    duration = 60
    heartbeats(script, duration)

    def vehicle_utc_us(t_us: int) -> int:
        return BASE_TIME_US + t_us + SKEW_OFFSET_US + t_us * SKEW_DRIFT_PPM // 1_000_000

    def vehicle_boot_us(t_us: int) -> int:
        return SKEW_BOOT_US + t_us + t_us * SKEW_DRIFT_PPM // 1_000_000

    timesync_rtt, ping_rtt = [], []
    for sec in range(duration):
        t = sec * 1_000_000 + 200_000 + rng.randint(0, 999)
        script.append((t, "vehicle", lambda mav, t=t: mav.system_time_encode(vehicle_utc_us(t),
                                                                             vehicle_boot_us(t) // 1000)))
        for q in range(4):
            ta = sec * 1_000_000 + q * 250_000 + 50_000 + rng.randint(0, 999)
            script.append((ta, "vehicle", lambda mav, ta=ta: mav.attitude_encode(
                vehicle_boot_us(ta) // 1000, 0.01, -0.02, 1.5, 0.0, 0.0, 0.0)))
        if sec % 2 == 0:
            tq = sec * 1_000_000 + 600_000 + rng.randint(0, 999)
            rtt = rng.randint(1_500, 9_000)
            timesync_rtt.append(rtt)
            ts1 = (BASE_TIME_US + tq) * 1000  # the GCS clock is the capture clock, in ns
            script.append((tq, "gcs", lambda mav, ts1=ts1: mav.timesync_encode(0, ts1)))
            script.append((tq + rtt, "vehicle", lambda mav, ts1=ts1, tr=tq + rtt // 2: mav.timesync_encode(
                vehicle_boot_us(tr) * 1000, ts1)))
        if sec % 5 == 0:
            tp = sec * 1_000_000 + 800_000 + rng.randint(0, 999)
            rtt = rng.randint(1_000, 6_000)
            ping_rtt.append(rtt)
            seq = sec // 5
            script.append((tp, "gcs", lambda mav, tp=tp, seq=seq: mav.ping_encode(BASE_TIME_US + tp, seq, 0, 0)))
            script.append((tp + rtt, "vehicle", lambda mav, tp=tp, seq=seq: mav.ping_encode(
                BASE_TIME_US + tp, seq, GCS_SYSID, GCS_COMPID)))

    endpoints = {"vehicle": Endpoint(mav2, VEHICLE_SYSID, VEHICLE_COMPID, link_id=VEHICLE_LINK_ID),
                 "gcs": Endpoint(mav2, GCS_SYSID, GCS_COMPID)}
    sends = pack_script(script, endpoints, sign_time=lambda side, t_us: vehicle_utc_us(t_us))
    flow = UdpFlow({"vehicle": (LOOPBACK_V4, VEHICLE_UDP_PORT), "gcs": (LOOPBACK_V4, GCS_UDP_PORT)}, rng)
    pkts = [flow.packet(s) for s in sends]
    offsets = write_pcap(outdir / "clock_skew.pcap", LINKTYPE_ETHERNET, pkts)
    summary = summarize_packets("pcap", [LINKTYPE_ETHERNET], pkts, offsets)
    summary["truth"] = {"vehicle_utc_offset_s": SKEW_OFFSET_US / 1e6, "vehicle_drift_ppm": SKEW_DRIFT_PPM,
                        "vehicle_boot_before_capture_s": SKEW_BOOT_US / 1e6,
                        "timesync_rtt_ms": [r / 1000 for r in timesync_rtt],
                        "ping_rtt_ms": [r / 1000 for r in ping_rtt]}
    return summary


# --------------------------------------------------------------------------------------------------
# Captures for the security layer: SecureMAV payload encryption, the X25519 key exchange (docs/security.md)
# --------------------------------------------------------------------------------------------------

SECUREMAV_AES_METHOD = 2  # SecureMAV's AES method id is not public: this capture uses 2 (--cipher 2=...)
SECUREMAV_AES_KEY = bytes.fromhex("7C852089FFDB16126DBEE7C968A751B5")  # their published test key
SECUREMAV_XOR_METHOD = 7  # SecureMAV's test cipher: XOR 0xAB
SECUREMAV_START_US = 5_000_000  # encryption switched on 5 s into the capture
KEX_GCS_PRIVATE = hashlib.sha256(b"mavscope key exchange: gcs static key").digest()
KEX_EPOCHS = ((1, 3_000_000), (2, 12_000_000), (3, 22_000_000))  # (key id, capture time of the exchange)
KEX_AES_GCM_METHOD = 6
KEX_MSGID = 65_100  # MAVSCOPE_KEY_EXCHANGE (dissectors/mavscope.xml)


def kex_vehicle_private(key_id: int) -> bytes:
    return hashlib.sha256(f"mavscope key exchange: vehicle epoch {key_id}".encode()).digest()


def kex_crc_extra() -> int:
    """CRC_EXTRA of MAVSCOPE_KEY_EXCHANGE as pymavlink's parser computes it from the XML."""
    from pymavlink.generator import mavparse

    xml = mavparse.MAVXML(str(REPO / "dissectors" / "mavscope.xml"), mavparse.PROTOCOL_2_0)
    return next(m.crc_extra for m in xml.message if m.id == KEX_MSGID)


class SecureSender:
    """A sender whose payloads pymavlink encodes and mavscope's security encoder encrypts and signs
    (SecureMAV's order: encrypt, then CRC and signature over the ciphertext)."""

    def __init__(self, sysid: int, compid: int, link_id: int) -> None:
        self.ep = Endpoint(mav2, sysid, compid)
        self.link_id = link_id
        self.timestamp = 0

    def payload(self, build: Callable[[Any], Any]) -> tuple[int, bytes, int]:
        msg = build(self.ep.mav)
        data = msg.pack(self.ep.mav)
        return msg.get_msgId(), data[10:10 + data[1]], msg.crc_extra

    def frame(self, t_us: int, msgid: int, payload: bytes, crc_extra: int, signing: Any = None,
              **cipher: Any) -> Frame:
        from mavscope.security.encode import encode_frame

        seq = self.ep.next_seq()
        if signing is not None:
            self.timestamp = max(self.timestamp + 1, (BASE_TIME_US + t_us - SIGNING_EPOCH_US) // 10)
        data = encode_frame(msgid, payload, crc_extra, seq=seq, sysid=self.ep.mav.srcSystem,
                            compid=self.ep.mav.srcComponent, signing=signing, link_id=self.link_id,
                            timestamp=self.timestamp, **cipher)
        return Frame(data, self.ep.mav.srcSystem, self.ep.mav.srcComponent, seq, msgid, 2, signing is not None)


def _udp_capture(outdir: Path, name: str, sends: list[Send], rng: Random) -> dict[str, Any]:
    flow = UdpFlow({"vehicle": (LOOPBACK_V4, VEHICLE_UDP_PORT), "gcs": (LOOPBACK_V4, GCS_UDP_PORT)}, rng)
    pkts = [flow.packet(s) for s in sorted(sends, key=lambda s: s.t_us)]
    offsets = write_pcap(outdir / name, LINKTYPE_ETHERNET, pkts)
    return summarize_packets("pcap", [LINKTYPE_ETHERNET], pkts, offsets)



def _secure_heartbeat_and_status(script: list[Any], rng: Random, sec: int, quad: Any, state: Any) -> None:
    """The vehicle's HEARTBEAT and SYS_STATUS of second `sec` in the secure sessions' scripts."""
    script.append((sec * 1_000_000 + 1_000 + rng.randint(0, 500), "vehicle", lambda mav: quad(mav, state, 0)))
    script.append((sec * 1_000_000 + 2_000 + rng.randint(0, 500), "vehicle",
                   lambda mav: mav.sys_status_encode(SENSORS_PRESENT, SENSORS_PRESENT, SENSORS_PRESENT, 250,
                                                     15_800 - sec * 2, -1, 87 - sec // 4, 0, 0, 0, 0, 0, 0)))

def securemav_udp(outdir: Path) -> dict[str, Any]:
    """20 s, plaintext for 5 s, then SecureMAV: vehicle payloads AES-128-CTR (method 2, counter restarted
    every frame), GCS heartbeats XOR 0xAB (method 7). Vehicle frames are signed over the ciphertext."""
    from mavscope.security.keys import SigningKey

    rng = Random(15)
    signing = SigningKey("capture", SIGNING_KEY)
    vehicle = SecureSender(VEHICLE_SYSID, VEHICLE_COMPID, VEHICLE_LINK_ID)
    gcs = SecureSender(GCS_SYSID, GCS_COMPID, GCS_LINK_ID)
    state = vehicle_state(SHORT_STORY, 0.0)
    quad = _heartbeat(MAV_AUTOPILOT_PX4)
    script: list[tuple[int, str, Callable[[Any], Any]]] = []
    for sec in range(20):
        _secure_heartbeat_and_status(script, rng, sec, quad, state)
        for q in range(4):
            t = sec * 1_000_000 + q * 250_000 + 100_000 + rng.randint(0, 999)
            script.append((t, "vehicle", lambda mav, t=t, q=q: mav.attitude_encode(
                VEHICLE_BOOT_OFFSET_MS + t // 1000, 0.01 * q, -0.02, 1.5 + t / 1e9, 0.001, 0.0, -0.002)))
        script.append((sec * 1_000_000 + 500_000 + rng.randint(0, 2_000), "gcs",
                       lambda mav: gcs_heartbeat(mav, state, 0)))
    sends: list[Send] = []
    encrypted = {"vehicle": 0, "gcs": 0}
    for t_us, side, build in sorted(script, key=lambda e: e[0]):
        sender = vehicle if side == "vehicle" else gcs
        msgid, payload, crc_extra = sender.payload(build)
        cipher: dict[str, Any] = {}
        if t_us >= SECUREMAV_START_US:
            encrypted[side] += 1
            cipher = ({"method": SECUREMAV_AES_METHOD, "scheme": "aes-128-ctr", "key": SECUREMAV_AES_KEY}
                      if side == "vehicle" else {"method": SECUREMAV_XOR_METHOD, "scheme": "xor", "key": b"\xab"})
        frame = sender.frame(t_us, msgid, payload, crc_extra, signing if side == "vehicle" else None, **cipher)
        sends.append(Send(t_us, side, [frame]))
    summary = _udp_capture(outdir, "securemav_udp.pcap", sends, rng)
    summary["truth"] = {"aes_method": SECUREMAV_AES_METHOD, "aes_key": SECUREMAV_AES_KEY.hex(), "aes_iv": "00" * 16,
                        "xor_method": SECUREMAV_XOR_METHOD, "encrypted_from_s": SECUREMAV_START_US / 1e6,
                        "encrypted_vehicle_frames": encrypted["vehicle"], "encrypted_gcs_frames": encrypted["gcs"]}
    return summary


def key_exchange_udp(outdir: Path) -> dict[str, Any]:
    """30 s: unsigned plaintext for 3 s, then MAVSCOPE_KEY_EXCHANGE (X25519) opens epoch 1; re-keyed at
    12 s (epoch 2) and 22 s (epoch 3). From each exchange both sides sign with the epoch's signing key
    and the vehicle encrypts ATTITUDE and SYS_STATUS with the aes-gcm profile (method 6, session id =
    key id); HEARTBEATs stay readable."""
    from cryptography.hazmat.primitives import serialization
    from cryptography.hazmat.primitives.asymmetric.x25519 import X25519PrivateKey

    from mavscope.security.kex import derive_epoch_keys, shared_secret
    from mavscope.security.keys import SigningKey

    def pub(private: bytes) -> bytes:
        return X25519PrivateKey.from_private_bytes(private).public_key().public_bytes(
            serialization.Encoding.Raw, serialization.PublicFormat.Raw)

    rng = Random(16)
    crc_extra = kex_crc_extra()
    vehicle = SecureSender(VEHICLE_SYSID, VEHICLE_COMPID, VEHICLE_LINK_ID)
    gcs = SecureSender(GCS_SYSID, GCS_COMPID, GCS_LINK_ID)
    gcs_pub = pub(KEX_GCS_PRIVATE)
    state = vehicle_state(SHORT_STORY, 0.0)
    quad = _heartbeat(MAV_AUTOPILOT_PX4)
    script: list[tuple[int, str, Any]] = []
    for sec in range(30):
        _secure_heartbeat_and_status(script, rng, sec, quad, state)
        for q in range(2):
            t = sec * 1_000_000 + q * 500_000 + 100_000 + rng.randint(0, 999)
            script.append((t, "vehicle", lambda mav, t=t: mav.attitude_encode(
                VEHICLE_BOOT_OFFSET_MS + t // 1000, 0.01, -0.02, 1.5 + t / 1e9, 0.001, 0.0, -0.002)))
        script.append((sec * 1_000_000 + 500_000 + rng.randint(0, 2_000), "gcs",
                       lambda mav: gcs_heartbeat(mav, state, 0)))
    epochs = []
    for key_id, t_ex in KEX_EPOCHS:
        v_priv = kex_vehicle_private(key_id)
        script.append((t_ex, "gcs", ("kex", key_id, gcs_pub, (VEHICLE_SYSID, VEHICLE_COMPID))))
        script.append((t_ex + 50_000, "vehicle", ("kex", key_id, pub(v_priv), (GCS_SYSID, GCS_COMPID))))
        signing, gcm = derive_epoch_keys(shared_secret(v_priv, gcs_pub), key_id, pub(v_priv), gcs_pub)
        epochs.append({"key_id": key_id, "exchange_s": t_ex / 1e6, "vehicle_private": v_priv.hex(),
                       "signing_key": signing.hex(), "aes_gcm_key": gcm.hex(), "t_us": t_ex,
                       "signing": SigningKey(f"ecdh-{key_id}", signing), "gcm": gcm})
    counters: dict[int, int] = {}
    sends: list[Send] = []
    for t_us, side, build in sorted(script, key=lambda e: e[0]):
        sender = vehicle if side == "vehicle" else gcs
        current = [e for e in epochs if e["t_us"] + 200_000 <= t_us]  # both sides switch 200 ms after
        epoch = current[-1] if current else None
        signing_key = epoch["signing"] if epoch is not None else None
        if isinstance(build, tuple):  # the key exchange: sent in clear, signed with the previous epoch's key
            _, key_id, public, target = build
            payload = struct.pack("<QIBB32s", BASE_TIME_US + t_us, key_id, *target, public)
            previous = [e for e in epochs if e["key_id"] < key_id]
            sk = previous[-1]["signing"] if previous else None
            sends.append(Send(t_us, side, [sender.frame(t_us, KEX_MSGID, payload, crc_extra, sk)]))
            continue
        msgid, payload, extra = sender.payload(build)
        cipher: dict[str, Any] = {}
        if epoch is not None and side == "vehicle" and msgid != 0:
            n = counters.get(epoch["key_id"], 0)
            counters[epoch["key_id"]] = n + 1
            cipher = {"method": KEX_AES_GCM_METHOD, "scheme": "aes-gcm", "key": epoch["gcm"],
                      "session_id": epoch["key_id"], "counter": n}
        sends.append(Send(t_us, side, [sender.frame(t_us, msgid, payload, extra, signing_key, **cipher)]))
    summary = _udp_capture(outdir, "key_exchange_udp.pcap", sends, rng)
    summary["truth"] = {
        "gcs_private": KEX_GCS_PRIVATE.hex(), "gcs_public": gcs_pub.hex(), "aes_gcm_method": KEX_AES_GCM_METHOD,
        "epochs": [{k: v for k, v in e.items() if k not in ("signing", "gcm", "t_us")} for e in epochs],
        "encrypted_frames": sum(counters.values()),
    }
    return summary


def render_security_captures(expected: dict[str, Any]) -> str:
    """The README section on securemav_udp.pcap and key_exchange_udp.pcap: keys and what to expect."""
    sm = expected["securemav_udp.pcap"]["truth"]
    kx = expected["key_exchange_udp.pcap"]["truth"]
    epochs = "\n".join(f"| {e['key_id']} | {e['exchange_s']} | `{e['vehicle_private']}` | `{e['signing_key']}` | "
                       f"`{e['aes_gcm_key']}` |" for e in kx["epochs"])
    aes_cipher = f"{sm['aes_method']}=aes-128-ctr:hex:{sm['aes_key']}"
    return f"""
## Security captures (`mavscope verify`, `audit`, `read --key/--cipher/--ecdh-private`; docs/security.md)

`securemav_udp.pcap`: SecureMAV payload encryption from {sm['encrypted_from_s']} s on. Vehicle payloads are
AES-128-CTR (method {sm['aes_method']}, SecureMAV's test key `{sm['aes_key']}`, IV 16 zero bytes, counter restarted
for every frame: {sm['encrypted_vehicle_frames']} frames); GCS heartbeats use SecureMAV's test cipher (method
{sm['xor_method']}, XOR 0xAB: {sm['encrypted_gcs_frames']} frames). Vehicle frames are signed (key above, link
{VEHICLE_LINK_ID}) over the ciphertext, as SecureMAV computes CRC and signature after encrypting. The plaintext
frames of the first seconds are known plaintext for `mavscope audit` (keystream-reuse):

    mavscope read captures/securemav_udp.pcap --key passphrase:{SIGNING_PASSPHRASE} --cipher {aes_cipher}
    mavscope audit captures/securemav_udp.pcap

`key_exchange_udp.pcap`: MAVSCOPE_KEY_EXCHANGE (id 65100, X25519) between the GCS (static key) and the
vehicle (a fresh key per epoch), unsigned plaintext before the first exchange, re-keyed twice. Both sides
switch to an epoch's keys 200 ms after its exchange; each exchange after the first is signed with the
previous epoch's key. The vehicle encrypts ATTITUDE and SYS_STATUS with the aes-gcm profile (method
{kx['aes_gcm_method']}, session id = key id, counter from 0 per epoch: {kx['encrypted_frames']} frames).
GCS private key `{kx['gcs_private']}` (public `{kx['gcs_public']}`):

    mavscope read captures/key_exchange_udp.pcap --ecdh-private hex:{kx['gcs_private']}
    mavscope verify captures/key_exchange_udp.pcap --ecdh-private hex:{kx['gcs_private']}

| key id | exchange at s | vehicle private key | signing key (HKDF) | aes-gcm master key (HKDF) |
|---|---|---|---|---|
{epochs}
"""


# --------------------------------------------------------------------------------------------------
# expected.json and README.md
# --------------------------------------------------------------------------------------------------


def dump_expected(expected: dict[str, Any]) -> str:
    """JSON with one frame per line: readable and diff-friendly."""
    lines = ["{"]
    for n, (name, entry) in enumerate(expected.items()):
        lines.append(f"  {json.dumps(name)}: {{")
        items = list(entry.items())
        for i, (key, value) in enumerate(items):
            comma = "," if i < len(items) - 1 else ""
            if key.startswith("frame_") or key == "cases":
                inner = ",\n".join(f"      {json.dumps(v)}" for v in value)
                body = f"[\n{inner}\n    ]" if value else "[]"
                lines.append(f"    {json.dumps(key)}: {body}{comma}")
            else:
                lines.append(f"    {json.dumps(key)}: {json.dumps(value)}{comma}")
        lines.append("  }" + ("," if n < len(expected) - 1 else ""))
    lines.append("}")
    return "\n".join(lines) + "\n"


CAPTURE_NOTES = {
    "px4_sitl_udp.pcap": "PX4 SITL <-> QGC on 127.0.0.1:14580 <-> :14550, 60 s: telemetry, mission upload "
                         "(4 items), arm, DO_REPOSITION (COMMAND_INT), RTL; some datagrams hold 2-3 frames; "
                         "an ARP packet and a DNS query as noise",
    "px4_sitl_tcp.pcap": "the same kind of session over TCP to 127.0.0.1:5760, 20 s: handshake, frames split "
                         "across segments, pure ACKs, one retransmission, one out-of-order pair, FIN",
    "mavlink_v1_udp.pcap": "MAVLink v1 (ArduCopter-style), 20 s: HEARTBEAT, SYS_STATUS, ATTITUDE, GPS_RAW_INT, "
                           "COMMAND_LONG arm + COMMAND_ACK",
    "signed_udp.pcap": "every frame signed (vehicle link 0, GCS link 1), 20 s, arm and RTL with their ACKs",
    "damaged.pcap": "one error case per record, see below",
    "px4_sitl.tlog": "the vehicle's frames of the first 30 s of px4_sitl_udp.pcap as a QGC tlog",
    "serial_dump.raw": "10 s of the vehicle's frames as a serial byte stream, garbage between frames, one frame "
                       "cut short",
    "px4_sitl_sll2.pcapng": "two interfaces: Linux SLL2 + IPv6 [::1] (vehicle 1, µs) and Ethernet + 802.1Q VLAN 10 "
                            "+ IPv4 192.168.10.0/24 (vehicle 2, ns)",
}
CAPTURE_NOTES |= {
    "stats_loss.pcap": "30 s, one frame per datagram; 44 vehicle frames and 2 GCS heartbeats removed, one "
                       "datagram duplicated, 3 vehicle frames with a bad CRC (truth below)",
    "mission_resend.pcap": "mission transfers: a download, an upload with a resent item, a refused fence upload, "
                           "an abandoned upload (truth below)",
    "commands_ack.pcap": "commands and ACKs: accepted, denied, failed, a retry, an unanswered one, a command from "
                         "a new sysid, a replayed command, SETUP_SIGNING (truth below)",
    "clock_skew.pcap": "60 s, vehicle clock 2.5 s ahead gaining 250 ppm: SYSTEM_TIME, signed frames, TIMESYNC, "
                       "PING (truth below)",
}
CAPTURE_NOTES |= {
    "securemav_udp.pcap": "SecureMAV payload encryption: 5 s plaintext, then vehicle payloads AES-128-CTR (method 2) "
                          "and GCS heartbeats XOR 0xAB (method 7); vehicle frames signed (keys below)",
    "key_exchange_udp.pcap": "X25519 key exchange (MAVSCOPE_KEY_EXCHANGE) with re-keying: signed frames and aes-gcm "
                             "payloads (method 6) under three epochs' keys (keys below)",
}
LINKTYPE_NAMES = {LINKTYPE_ETHERNET: "Ethernet (1)", LINKTYPE_LINUX_SLL2: "Linux SLL2 (276)"}


def render_readme(expected: dict[str, Any], cases: Sequence[DamageCase]) -> str:
    key_hex = SIGNING_KEY.hex()
    udp, tcp, serial = expected["px4_sitl_udp.pcap"], expected["px4_sitl_tcp.pcap"], expected["serial_dump.raw"]
    rows = []
    for name, e in expected.items():
        link = ", ".join(LINKTYPE_NAMES[lt] for lt in e["linktypes"]) or \
            {"tlog": "tlog (no link layer)", "raw": "raw byte stream"}[e["format"]]
        note = CAPTURE_NOTES[name] + (f"; key `{key_hex}`" if name == "signed_udp.pcap" else "")
        rows.append(f"| `{name}` | {note} | {link} | {e['records'] if e['records'] is not None else '-'} | "
                    f"{e['frames']} |")
    counts = [f"| `{n}` | {e['frames']} | {e['crc_ok']} | {e['crc_bad']} | {e['crc_unchecked']} | {e['v1']} | "
              f"{e['v2']} | {e['signed']} | {e['truncated']} | {e['skipped_bytes']} |" for n, e in expected.items()]
    damage = [f"| {c.record} | {c.what} | {c.expect} |" for c in cases]
    nl = "\n"
    return f"""# Sample captures

Generated by `scripts/make_captures.py`; do not edit by hand (this README and `expected.json` are
generated too). Regenerate with

    python scripts/make_captures.py captures        # or: make captures

The output is the same byte for byte on every run and machine; `tests/test_captures_reproducible.py`
checks that, and checks `px4_sitl_udp.pcap` against pymavlink.

MAVLink frames are encoded and signed by pymavlink 2.4.50 (`pymavlink.dialects.v20.common`,
`pymavlink.dialects.v10.common`), packets built by scapy with correct IP/UDP/TCP checksums, and the files
written with `struct`. Capture time starts at 2026-03-14T10:00:00Z (Unix {BASE_TIME_US // 1_000_000}).

| file | what it shows | link type | records | frames |
|---|---|---|---|---|
{nl.join(rows)}

Endpoints: vehicle sysid {VEHICLE_SYSID} compid {VEHICLE_COMPID} (PX4, MAV_TYPE_QUADROTOR; home 47.3977419 N
8.5455938 E, 488 m), GCS sysid {GCS_SYSID} compid {GCS_COMPID}. The vehicle's `time_boot_ms` is capture time +
{VEHICLE_BOOT_OFFSET_MS} ms; its UTC clock (SYSTEM_TIME, GPS_RAW_INT) runs {VEHICLE_UTC_OFFSET_US} µs ahead of
the capture clock.

## Signing key (`signed_udp.pcap`)

Passphrase `{SIGNING_PASSPHRASE}`, key = SHA-256(passphrase) as MAVProxy derives it:

    {key_hex}

Vehicle frames use link id {VEHICLE_LINK_ID}, GCS frames link id {GCS_LINK_ID}. Signature timestamps are the
capture time in units of 10 µs since 2015-01-01T00:00:00Z (strictly increasing per sender, as pymavlink
adds one after each frame).

## What a correct decoder reports

| file | frames | CRC ok | CRC bad | CRC unchecked | v1 | v2 | signed | truncated | skipped bytes |
|---|---|---|---|---|---|---|---|---|---|
{nl.join(counts)}

Definitions:

- **frame**: a complete frame (header, payload of the length the header says, CRC, and the signature when
  incompat flag 0x01 is set) that the decoder reports, whatever its CRC verdict. Bytes that TCP
  retransmits are counted once.
- **CRC ok / bad / unchecked**: `unchecked` when the message id is in no dialect the decoder knows, so its
  CRC_EXTRA is unknown (here only id {UNKNOWN_MSGID}, which is in no pymavlink dialect); never `bad`.
- **truncated**: a frame cut short by the end of its datagram, of the capture record, or (in a byte stream)
  by the next frame: reported as a truncated-frame note, **not** counted under frames.
- **skipped bytes**: bytes that belong to no frame and to no truncated frame (garbage, stray start bytes).

`expected.json` holds these counts per file and, per frame in capture order, `frame_list` entries
`[record_number, index_in_record, sysid, compid, seq, msgid]`, plus the parallel lists `frame_offsets`
(file offset of the frame's first byte) and `frame_crc` (`ok`/`bad`/`unchecked`), and `truncated_list`:
`[record_number, file offset]` of each truncated frame's first byte.

- `record_number` is 1-based over all records of the file (pcapng: over all packet blocks of both
  interfaces; tlog: one record per frame). For `serial_dump.raw` it is `null`: a raw stream has no records
  (the reader's chunking decides them), and `index_in_record` is the frame's 1-based position in the
  stream among the frames listed.
- A frame belongs to the record in which it completes: for datagrams the record holding it; for TCP the
  record after which the stream is contiguous up to the frame's last byte (retransmitted copies add
  nothing; a frame ending in the early-arriving half of the out-of-order pair completes with the
  later record, as Wireshark shows a reassembled PDU). `index_in_record` is 1-based among the frames
  completing in that record, in stream order. This is `Frame.record` / `Frame.index` in mavscope.

## `damaged.pcap`, record by record

| record | what is in it | what a correct tool reports |
|---|---|---|
{nl.join(damage)}

## `serial_dump.raw`

Garbage (no 0xFD/0xFE) sits between some frames ({serial['skipped_bytes']} bytes in all), and one frame
is cut after 16 bytes at file offset {serial['truncated_list'][0][1]}, directly followed by the next frame: a
correct tool reports the cut frame as a truncated frame (not as a frame) and still decodes the frame that
follows it.

## Other events

- `px4_sitl_udp.pcap`: records {udp['events']['noise_records']} are not MAVLink (ARP, DNS, ARP, DNS).
- `px4_sitl_tcp.pcap`: the handshake is records 1-3 and the FIN exchange the last four; record
  {tcp['events']['retransmission'][1]} retransmits record {tcp['events']['retransmission'][0]} (same sequence \
number, same bytes); records {tcp['events']['out_of_order'][0]} and {tcp['events']['out_of_order'][1]} are \
out of order (the later bytes first).

## Where pymavlink's robust parser differs

pymavlink (`robust_parsing = True`) is not a correct tool for `damaged.pcap` and `serial_dump.raw`, so
a cross-check against it must expect these differences:

- `damaged.pcap` record 6: pymavlink returns `MAVLink_unknown` (CRC not checkable), not bad data.
- `damaged.pcap` record 7: pymavlink drops the frame with the unknown incompat flag (bad data).
- `damaged.pcap` record 8: pymavlink reads the stray `fe` as a v1 frame of 253 payload bytes, waits for
  bytes the datagram does not have, and so finds neither frame.
- `serial_dump.raw`: pymavlink reads the cut frame's length, takes the next frame's bytes as its tail
  (bad CRC) and loses that next frame: it finds one CRC-valid frame fewer than listed here.
"""


def render_analysis_truth(expected: dict[str, Any]) -> str:
    """The README section on the captures built for statistics, mission, command and clock analysis."""
    loss = expected["stats_loss.pcap"]["truth"]
    mission = expected["mission_resend.pcap"]["truth"]["transfers"]
    cmds = expected["commands_ack.pcap"]["truth"]
    clock = expected["clock_skew.pcap"]["truth"]
    links = "\n".join(f"| {k} | {v['sent']} | {v['received']} | {v['lost']} | {v['duplicates']} | {v['crc_bad']} |"
                      for k, v in loss["links"].items())
    transfers = "\n".join(
        f"| {i} | {t['direction']} | {t['from']} -> {t['to']} | {t['mission_type']} | {t['count']} | "
        f"{'yes' if t['complete'] else 'no'} | "
        f"{', '.join(f'{k}: {v}' for k, v in t.items() if k in ('resent', 'result', 'reason', 'items_received'))} |"
        for i, t in enumerate(mission, 1))
    commands = "\n".join(
        f"| {c['command']} | {c['kind']} | {c['from']} | {c['result'] if c['result'] is not None else 'none'} | "
        f"{c['retries']} | {c['latency_ms'] if c['latency_ms'] is not None else '-'} |" for c in cmds["commands"])
    return f"""
## Analysis truth (`stats`, `mission`, `commands`, `timeline`, expert findings)

`stats_loss.pcap`: {loss['removed_vehicle_frames']}, and GCS {loss['removed_gcs_frames']}, were removed; one
vehicle datagram appears twice (a duplicate, not a loss); three vehicle frames have one payload bit flipped
(header intact, CRC bad).

| link (sysid/compid) | frames sent | frames in the capture | lost | duplicates | CRC bad |
|---|---|---|---|---|---|
{links}

`mission_resend.pcap` (items as MISSION_ITEM_INT, frame MAV_FRAME_GLOBAL_RELATIVE_ALT_INT):

| # | direction | from -> to | mission type | count | complete | detail |
|---|---|---|---|---|---|---|
{transfers}

`commands_ack.pcap` (MAV_RESULT: 0 accepted, 2 denied, 4 failed; latency from the first transmission to
the ACK; the last row is record {cmds['replay_record']}, a byte-for-byte replay of record
{cmds['commands'][-1]['replay_of_record']}; the command from `rogue` comes from sysid {cmds['rogue'][0]} on UDP
port {cmds['rogue'][2]}, a system not seen before; record {cmds['setup_signing_record']} is a SETUP_SIGNING that
carries a key in clear):

| command | message | from | result | retries | latency ms |
|---|---|---|---|---|---|
{commands}

`clock_skew.pcap`: the GCS clock is the capture clock. The vehicle's UTC clock (SYSTEM_TIME.time_unix_usec and
its signature timestamps, link {VEHICLE_LINK_ID}) is {clock['vehicle_utc_offset_s']} s ahead at the capture
start and gains {clock['vehicle_drift_ppm']} ppm; its boot clock (time_boot_ms, TIMESYNC tc1) started
{clock['vehicle_boot_before_capture_s']} s (by its own clock) before the capture and drifts the same.
TIMESYNC round trips (ms): {', '.join(map(str, clock['timesync_rtt_ms']))}; PING round trips (ms):
{', '.join(map(str, clock['ping_rtt_ms']))}.
"""


# --------------------------------------------------------------------------------------------------


def make_all(outdir: Path) -> dict[str, Any]:
    """Write every capture, expected.json and README.md into outdir; return the expected results."""
    outdir.mkdir(parents=True, exist_ok=True)
    expected: dict[str, Any] = {}
    expected["px4_sitl_udp.pcap"], udp_sends = px4_sitl_udp(outdir)
    expected["px4_sitl_tcp.pcap"] = px4_sitl_tcp(outdir)
    expected["mavlink_v1_udp.pcap"] = mavlink_v1_udp(outdir)
    expected["signed_udp.pcap"] = signed_udp(outdir)
    expected["damaged.pcap"], cases = damaged(outdir)
    expected["damaged.pcap"]["cases"] = [[c.record, c.what, c.expect] for c in cases]
    expected["px4_sitl.tlog"] = px4_sitl_tlog(outdir, udp_sends)
    expected["serial_dump.raw"] = serial_dump(outdir, udp_sends)
    expected["px4_sitl_sll2.pcapng"] = px4_sitl_sll2(outdir)
    expected["stats_loss.pcap"] = stats_loss(outdir)
    expected["mission_resend.pcap"] = mission_resend(outdir)
    expected["commands_ack.pcap"] = commands_ack(outdir)
    expected["clock_skew.pcap"] = clock_skew(outdir)
    expected["securemav_udp.pcap"] = securemav_udp(outdir)
    expected["key_exchange_udp.pcap"] = key_exchange_udp(outdir)
    (outdir / "expected.json").write_text(dump_expected(expected), encoding="utf-8")
    (outdir / "README.md").write_text(render_readme(expected, cases) + render_analysis_truth(expected)
                                      + render_security_captures(expected), encoding="utf-8")
    return expected


def main(argv: Sequence[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) > 1 or (args and args[0] in ("-h", "--help")):
        print(__doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 2
    outdir = Path(args[0]) if args else DEFAULT_OUTDIR
    expected = make_all(outdir)
    for name, e in expected.items():
        print(f"{name:24} {e['frames']:5} frames  ok {e['crc_ok']}  bad {e['crc_bad']}  "
              f"unchecked {e['crc_unchecked']}  truncated {e['truncated']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
