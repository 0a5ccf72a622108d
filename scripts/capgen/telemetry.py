"""The vehicle's telemetry and the GCS's requests: message factories, periodic streams, and
`build_session`, which plans a whole session from a story and has pymavlink pack it in time order so
that each side's sequence numbers increase along the capture."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from random import Random
from types import ModuleType
from typing import Any

import pymavlink.dialects.v10.common as mav1

from .constants import (
    ARDUCOPTER_MODES,
    BASE_TIME_US,
    DEG_TO_RAD,
    GCS_COMPID,
    GCS_LINK_ID,
    GCS_SYSID,
    GPS_FIX_TYPE_3D_FIX,
    HOME_ALT_M,
    MAV_AUTOPILOT_INVALID,
    MAV_AUTOPILOT_PX4,
    MAV_CMD_COMPONENT_ARM_DISARM,
    MAV_CMD_DO_REPOSITION,
    MAV_CMD_NAV_RETURN_TO_LAUNCH,
    MAV_CMD_NAV_TAKEOFF,
    MAV_CMD_NAV_WAYPOINT,
    MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    MAV_MISSION_ACCEPTED,
    MAV_MISSION_TYPE_MISSION,
    MAV_MODE_FLAG_AUTO_ENABLED,
    MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
    MAV_MODE_FLAG_GUIDED_ENABLED,
    MAV_MODE_FLAG_MANUAL_INPUT_ENABLED,
    MAV_MODE_FLAG_SAFETY_ARMED,
    MAV_MODE_FLAG_STABILIZE_ENABLED,
    MAV_RESULT_ACCEPTED,
    MAV_STATE_ACTIVE,
    MAV_STATE_STANDBY,
    MAV_TYPE_GCS,
    MAV_TYPE_QUADROTOR,
    NAN,
    PX4_MODES,
    SENSORS_PRESENT,
    VEHICLE_BOOT_OFFSET_MS,
    VEHICLE_COMPID,
    VEHICLE_LINK_ID,
    VEHICLE_SYSID,
    VEHICLE_UTC_OFFSET_US,
)
from .frames import Endpoint, Send
from .story import Story, VehicleState, to_degE7, vehicle_state

MessageFactory = Callable[[Any, VehicleState, int], Any]  # (mav, state, t_us) -> message


@dataclass(frozen=True)
class Stream:
    """A periodic telemetry message."""

    name: str
    period_ms: int
    phase_ms: int
    factory: MessageFactory



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


def vehicle_heartbeat(autopilot: int) -> MessageFactory:
    """The vehicle's HEARTBEAT: base mode and custom mode follow the armed state and the flight mode."""
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
        "HEARTBEAT": (1000, 0, vehicle_heartbeat(profile.autopilot)),
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
    """COMMAND_ACK (accepted) to the GCS; MAVLink v1 has no target fields."""
    def build(mav: Any, s: VehicleState, t_us: int) -> Any:
        if isinstance(mav, mav1.MAVLink):
            return mav.command_ack_encode(command, MAV_RESULT_ACCEPTED)
        return mav.command_ack_encode(command, MAV_RESULT_ACCEPTED, 0, 0, GCS_SYSID, GCS_COMPID)
    return build


def command_long(command: int, *params: float) -> MessageFactory:
    """COMMAND_LONG to the vehicle, unused params zero."""
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


PX4_STREAMS = ("HEARTBEAT", "SYS_STATUS", "ATTITUDE", "GLOBAL_POSITION_INT", "GPS_RAW_INT", "SYSTEM_TIME",
               "BATTERY_STATUS", "VFR_HUD")
