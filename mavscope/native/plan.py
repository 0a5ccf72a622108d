"""What the native `stats` accumulator needs to know, compiled from the Dialect and the analyses.

src/mavscope_native/acc.h ports StatsBuilder and the expert detectors that see every frame to C; what
they know besides their code comes from here as one byte string (its layout: plan.h), never written by
hand in C: the analyses' constants (read from their modules), the messages they test by name (their ids
in the loaded dialect, with the roles of Expert.decode, commanders.COMMANDING, control.WANTS, gnss.WANTS), the
offset and type of each field they read, the MAV_TYPE classes and mode names of mavlink/modes.py, the
control commands of ControlSources and the EKF flag bits of GnssAnomalies.

`build_plan` gives None when the dialect cannot be described to C exactly: a field the analyses read with
a type other than the one its C port reads (the C code reads a HEARTBEAT's `type` as uint8_t, math.hypot
of GLOBAL_POSITION_INT's vx and vy is exact only for 16-bit integers...), two messages of one name, a
message named UNKNOWN_<n> (the stream label of an unknown id), SETUP_SIGNING at another id than the
walker hands back, or a mode name C does not hold. `mavscope stats` then runs the pure path.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable

from mavscope.analysis import commanders, control, expert, framelist, gnss, sequence, stats, vehicles
from mavscope.analysis.expert import Expert
from mavscope.mavlink import modes
from mavscope.mavlink.dialect import Dialect, EnumDef, MessageDef

PLAN_MAGIC = b"MSSP"
PLAN_VERSION = 1


def int_constants() -> tuple[int, ...]:
    """plan.h MS_K_*, in order: read from the analyses' modules when a plan is built."""
    return (
        sequence.GAP_MIN, sequence.GAPS_KEPT, sequence.RESET_RUN, sequence.MAX_CHANNELS, sequence.MAX_EXTRA,
        sequence.LATE_WINDOW, stats.RATE_BINS, expert.COPIES_KEPT, vehicles.MAX_SENDERS, framelist.MAX_FRAMES,
        commanders.MAV_TYPE_GCS, control.MAV_CMD_DO_SET_MODE, control.MAV_CMD_COMPONENT_ARM_DISARM,
        control.MAV_MISSION_TYPE_MISSION, control.MAV_MISSION_TYPE_ALL, control.MAV_LANDED_STATE_IN_AIR,
        control.MAV_LANDED_STATE_TAKEOFF, control.MAV_LANDED_STATE_UNDEFINED, modes.MAV_AUTOPILOT_ARDUPILOTMEGA,
        modes.MAV_AUTOPILOT_INVALID, modes.MAV_AUTOPILOT_PX4, modes.MAV_MODE_FLAG_SAFETY_ARMED,
        modes.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, modes.PX4_MAIN_AUTO, modes.PX4_MAIN_POSCTL,
        gnss.GPS_FIX_TYPE_NO_GPS, gnss.GPS_FIX_TYPE_NO_FIX, gnss.GPS_FIX_TYPE_2D, gnss.GPS_FIX_TYPE_3D,
        gnss.UNKNOWN_SATS, gnss.UNKNOWN_VEL, gnss.MIN_SATS, gnss.UNIX_MIN_US, stats.MAX_STREAMS,
        stats.MAX_CONVERSATIONS, expert.MAX_NAMED, commanders.COMMANDERS_SHOWN, sequence.RING, gnss.MAX_EPISODES,
    )


# plan.h MS_D_*, in order
FLOAT_CONSTANTS: tuple[float, ...] = (
    control.MODE_WINDOW_S, control.STATE_FRESH_S, control.ALT_FLYING_M, gnss.EARTH_RADIUS_M, gnss.JUMP_MIN_M,
    gnss.SPEED_FACTOR, gnss.ACCEL_MPS2, gnss.MARGIN_M, gnss.NULL_ISLAND, gnss.MAX_GAP_S, gnss.COLLAPSE_WINDOW_S,
    gnss.VARIANCE_ALARM, gnss.TIME_JUMP_S, gnss.TIME_MISMATCH_S, gnss.REBOOT_BACK_S,
)

# plan.h MS_M_*: the message names the C port tests (any other message with a role is MS_M_OTHER, 1)
KINDS: dict[str, int] = {
    "HEARTBEAT": 2, "EXTENDED_SYS_STATE": 3, "GLOBAL_POSITION_INT": 4, "GPS_RAW_INT": 5, "GPS2_RAW": 6,
    "SYSTEM_TIME": 7, "EKF_STATUS_REPORT": 8, "ESTIMATOR_STATUS": 9, "SET_MODE": 10, "COMMAND_LONG": 11,
    "COMMAND_INT": 12, "MISSION_CLEAR_ALL": 13, "MISSION_COUNT": 14, "MANUAL_CONTROL": 15,
}
ROLE_DECODE, ROLE_COMMANDING, ROLE_CONTROL, ROLE_GNSS = 1, 2, 4, 8

# plan.h MS_F_*: the fields the C port reads, in slot order, and the wire types it reads each one as
_INTS = ("uint8_t", "int8_t", "uint16_t", "int16_t", "uint32_t", "int32_t")
_NUMBERS = (*_INTS, "uint64_t", "int64_t", "float", "double")  # read as Python floats (gnss._num)
SLOTS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("target_system", ("uint8_t",)), ("target", ("uint8_t",)), ("type", ("uint8_t",)), ("autopilot", ("uint8_t",)),
    ("base_mode", ("uint8_t",)), ("custom_mode", ("uint32_t",)), ("system_status", ("uint8_t",)),
    ("command", ("uint8_t", "uint16_t")), ("param1", ("float", "double")), ("param2", ("float", "double")),
    ("param3", ("float", "double")), ("mission_type", _INTS), ("count", _INTS), ("landed_state", _INTS),
    ("relative_alt", _INTS), ("lat", _NUMBERS), ("lon", _NUMBERS), ("vx", ("int8_t", "uint8_t", "int16_t")),
    ("vy", ("int8_t", "uint8_t", "int16_t")), ("time_boot_ms", _NUMBERS), ("time_usec", _NUMBERS),
    ("fix_type", _INTS), ("vel", _INTS), ("h_acc", _INTS), ("satellites_visible", _INTS),
    ("flags", _INTS), ("velocity_variance", _NUMBERS), ("pos_horiz_variance", _NUMBERS),
    ("vel_ratio", _NUMBERS), ("pos_horiz_ratio", _NUMBERS), ("time_unix_usec", _NUMBERS),
)
# which fields the analyses read of which message (a slot of another message stays empty)
_CLOCK = ("time_boot_ms", "time_usec")
_READS: dict[str, tuple[str, ...]] = {
    "HEARTBEAT": ("type", "autopilot", "base_mode", "custom_mode", "system_status"),
    "EXTENDED_SYS_STATE": ("landed_state", "relative_alt"),
    "GLOBAL_POSITION_INT": ("relative_alt", *_CLOCK, "lat", "lon", "vx", "vy"),
    "GPS_RAW_INT": (*_CLOCK, "lat", "lon", "fix_type", "satellites_visible", "vel", "h_acc"),
    "GPS2_RAW": (*_CLOCK, "lat", "lon", "fix_type", "satellites_visible", "vel", "h_acc"),
    "SYSTEM_TIME": (*_CLOCK, "time_unix_usec"),
    "EKF_STATUS_REPORT": (*_CLOCK, "flags", "velocity_variance", "pos_horiz_variance"),
    "ESTIMATOR_STATUS": (*_CLOCK, "flags", "vel_ratio", "pos_horiz_ratio"),
    "SET_MODE": ("base_mode", "custom_mode"),
    "COMMAND_LONG": ("command", "param1", "param2", "param3"),
    "COMMAND_INT": ("command", "param1", "param2", "param3"),
}
_TARGETS = ("target_system", "target")  # every commanding and control message
_CONTROL_READS = ("mission_type", "count")  # every control message (`clear`)
SETUP_SIGNING = 256  # the id the walker hands back (walk.c), where KeyLeaks looks for SETUP_SIGNING by name


class Unplannable(Exception):
    """The dialect cannot be described to the C accumulator exactly."""


def _names(enum: EnumDef | None, prefix: str) -> dict[int, str]:
    if enum is None:
        return {}
    return {value: entry.name.removeprefix(prefix) for value, entry in enum.entries.items()}


def _enum(entries: dict[int, str]) -> bytes:
    """An enum of the plan: (value, name) by value; values outside u32 can never be looked up."""
    out = []
    for value in sorted(v for v in entries if 0 <= v <= 0xFFFFFFFF):
        name = entries[value].encode()
        if len(name) > 255 or not name.isascii() or not all(0x20 <= c <= 0x7E for c in name):
            raise Unplannable(f"mode name {entries[value]!r}")
        out.append(struct.pack("<IB", value, len(name)) + name)
    return struct.pack("<I", len(out)) + b"".join(out)


def _bitmap(values: Iterable[int], size: int) -> bytes:
    bits = bytearray(size // 8)
    for v in values:
        if 0 <= v < size:
            bits[v >> 3] |= 1 << (v & 7)
    return bytes(bits)


def _message(md: MessageDef, roles: int) -> bytes:
    reads = set(_READS.get(md.name, ()))
    if roles & (ROLE_COMMANDING | ROLE_CONTROL):
        reads.update(_TARGETS)
    if roles & ROLE_CONTROL:
        reads.update(_CONTROL_READS)
    slots = []
    for name, types in SLOTS:
        fd = md.field(name) if name in reads else None
        if fd is None:
            slots.append(b"\0\0")
            continue
        if fd.type not in types or fd.array_length or fd.offset + fd.size > 255:
            raise Unplannable(f"{md.name}.{name} is {fd.type}[{fd.array_length}]")
        slots.append(struct.pack("<BB", _TYPE_CODES[fd.type], fd.offset))
    return struct.pack("<IBB", md.id, KINDS.get(md.name, 1), roles) + b"".join(slots)


# the type codes of table.h (MS_T_*)
_TYPE_CODES = {"uint8_t": 1, "int8_t": 2, "uint16_t": 3, "int16_t": 4, "uint32_t": 5, "int32_t": 6,
               "uint64_t": 7, "int64_t": 8, "float": 9, "double": 10}


def build_plan(dialect: Dialect) -> bytes | None:
    """The plan of `dialect` for `_native.Stats`, or None when it cannot be described exactly."""
    try:
        return _build(dialect)
    except Unplannable:
        return None


def _build(dialect: Dialect) -> bytes:
    names = [md.name for md in dialect.messages.values()]
    if len(set(names)) != len(names) or any(n.startswith("UNKNOWN_") for n in names):
        raise Unplannable("message names")
    signing = dialect.messages.get(SETUP_SIGNING)
    if any(md.name == "SETUP_SIGNING" for md in dialect.messages.values()) and (
            signing is None or signing.name != "SETUP_SIGNING"):
        raise Unplannable("SETUP_SIGNING")
    ex = Expert(dialect)
    messages = []
    for md in sorted(dialect.messages.values(), key=lambda m: m.id):
        roles = ((ROLE_DECODE if md.name in ex.decode else 0)
                 | (ROLE_COMMANDING if md.name in commanders.COMMANDING else 0)
                 | (ROLE_CONTROL if md.name in control.WANTS else 0) | (ROLE_GNSS if md.name in gnss.WANTS else 0))
        if roles or md.id == 0:
            messages.append(_message(md, roles))
    m = modes.modes_for(dialect)
    ardupilot: dict[str, int] = {}
    types = bytearray(b"\xff" * 256)
    for mav_type, enum_name in sorted(m.ardupilot.items()):
        if 0 <= mav_type < 256:
            types[mav_type] = ardupilot.setdefault(enum_name, len(ardupilot))
    enums = [_enum(_names(dialect.enums.get(n), n + "_")) for n in ardupilot]
    enums += [_enum(_names(dialect.enums.get("MAV_MODE"), "MAV_MODE_")), _enum(modes.PX4_MAIN_MODES),
              _enum(modes.PX4_AUTO_SUB_MODES), _enum(modes.PX4_POSCTL_SUB_MODES)]
    if len(enums) > 255:
        raise Unplannable("too many mode enums")
    g = gnss.GnssAnomalies(dialect)
    bits = (*g.ekf_bits, *g.est_bits)
    ints = int_constants()
    if not all(0 <= b < 1 << 64 for b in bits) or not all(-(1 << 63) <= k < 1 << 63 for k in ints):
        raise Unplannable("constants")
    return b"".join((
        PLAN_MAGIC, struct.pack("<IH", PLAN_VERSION, len(ints)),
        struct.pack(f"<{len(ints)}q", *ints),
        struct.pack("<H", len(FLOAT_CONSTANTS)), struct.pack(f"<{len(FLOAT_CONSTANTS)}d", *FLOAT_CONSTANTS),
        struct.pack("<I", len(messages)), *messages,
        _bitmap(m.aerial, 256), _bitmap(m.gcs, 256), _bitmap(m.not_vehicles, 256), bytes(types),
        struct.pack("<B", len(enums)), *enums,
        _bitmap(control.ControlSources(dialect).control_commands, 65536),
        struct.pack("<8Q", *bits),
    ))
