"""Flight modes and the armed state, as each autopilot encodes them in HEARTBEAT, SET_MODE and
MAV_CMD_DO_SET_MODE.

- ArduPilot (MAV_AUTOPILOT_ARDUPILOTMEGA) puts its mode number in `custom_mode` (with
  MAV_MODE_FLAG_CUSTOM_MODE_ENABLED in `base_mode`); the number means something else per vehicle: the
  dialect's enums COPTER_MODE, PLANE_MODE, ROVER_MODE, SUB_MODE and TRACKER_MODE (ardupilotmega.xml) name
  them, chosen by the HEARTBEAT's MAV_TYPE as ArduPilot's own frame types and pymavlink's mavutil map them
  (a Blimp, MAV_TYPE_AIRSHIP, has no enum in the XML: its mode is given as a number).
- PX4 (MAV_AUTOPILOT_PX4) packs a main mode and a sub mode: `custom_mode` = sub << 24 | main << 16 (the
  union in PX4's src/modules/commander/px4_custom_mode.h); DO_SET_MODE carries them as param2 and param3.
  No dialect XML has these enums, so they are transcribed below from that header.
- Anything else: the MAV_MODE entry of `base_mode` when it is one, else the custom mode's number.

Names are the enum entries without their prefix (COPTER_MODE_LOITER -> LOITER; PX4: AUTO.MISSION,
POSCTL.ORBIT, OFFBOARD), as QGroundControl, MAVProxy and mavros show them.
"""

from __future__ import annotations

from mavscope.mavlink.dialect import Dialect

MAV_AUTOPILOT_ARDUPILOTMEGA = 3
MAV_AUTOPILOT_INVALID = 8
MAV_AUTOPILOT_PX4 = 12
MAV_MODE_FLAG_SAFETY_ARMED = 128
MAV_MODE_FLAG_CUSTOM_MODE_ENABLED = 1

# PX4-Autopilot src/modules/commander/px4_custom_mode.h (main branch): enum PX4_CUSTOM_MAIN_MODE starts at
# MANUAL = 1; PX4_CUSTOM_SUB_MODE_AUTO at READY = 1 (7 was RTGS, deleted 2020-03-05, now
# RESERVED_DO_NOT_USE); PX4_CUSTOM_SUB_MODE_POSCTL at POSCTL = 0.
PX4_MAIN_MODES: dict[int, str] = {
    1: "MANUAL", 2: "ALTCTL", 3: "POSCTL", 4: "AUTO", 5: "ACRO", 6: "OFFBOARD", 7: "STABILIZED",
    8: "RATTITUDE_LEGACY", 9: "SIMPLE", 10: "TERMINATION", 11: "ALTITUDE_CRUISE",
}
PX4_MAIN_AUTO, PX4_MAIN_POSCTL = 4, 3
PX4_AUTO_SUB_MODES: dict[int, str] = {
    1: "READY", 2: "TAKEOFF", 3: "LOITER", 4: "MISSION", 5: "RTL", 6: "LAND", 7: "RESERVED_DO_NOT_USE",
    8: "FOLLOW_TARGET", 9: "PRECLAND", 10: "VTOL_TAKEOFF", 11: "EXTERNAL1", 12: "EXTERNAL2", 13: "EXTERNAL3",
    14: "EXTERNAL4", 15: "EXTERNAL5", 16: "EXTERNAL6", 17: "EXTERNAL7", 18: "EXTERNAL8",
}
PX4_POSCTL_SUB_MODES: dict[int, str] = {0: "POSCTL", 1: "ORBIT", 2: "SLOW"}

# MAV_TYPE entry names -> the ardupilotmega.xml enum naming that vehicle's custom modes.
_ARDUPILOT_ENUMS: tuple[tuple[tuple[str, ...], str], ...] = (
    (("MAV_TYPE_QUADROTOR", "MAV_TYPE_HEXAROTOR", "MAV_TYPE_OCTOROTOR", "MAV_TYPE_TRICOPTER",
      "MAV_TYPE_HELICOPTER", "MAV_TYPE_COAXIAL", "MAV_TYPE_DODECAROTOR", "MAV_TYPE_DECAROTOR"), "COPTER_MODE"),
    (("MAV_TYPE_FIXED_WING", "MAV_TYPE_VTOL_*"), "PLANE_MODE"),
    (("MAV_TYPE_GROUND_ROVER", "MAV_TYPE_SURFACE_BOAT"), "ROVER_MODE"),
    (("MAV_TYPE_SUBMARINE",), "SUB_MODE"),
    (("MAV_TYPE_ANTENNA_TRACKER",), "TRACKER_MODE"),
)
# MAV_TYPEs of systems that are not vehicles (ground stations, peripherals, onboard computers).
_NOT_VEHICLES = ("MAV_TYPE_GCS", "MAV_TYPE_ONBOARD_CONTROLLER", "MAV_TYPE_GIMBAL", "MAV_TYPE_ADSB", "MAV_TYPE_CAMERA",
                 "MAV_TYPE_CHARGING_STATION", "MAV_TYPE_FLARM", "MAV_TYPE_SERVO", "MAV_TYPE_ODID", "MAV_TYPE_BATTERY",
                 "MAV_TYPE_PARACHUTE", "MAV_TYPE_LOG", "MAV_TYPE_OSD", "MAV_TYPE_IMU", "MAV_TYPE_GPS", "MAV_TYPE_WINCH",
                 "MAV_TYPE_ILLUMINATOR")
# Vehicle classes for other analyses (in-flight checks): MAV_TYPEs that fly.
_AERIAL = ("MAV_TYPE_FIXED_WING", "MAV_TYPE_QUADROTOR", "MAV_TYPE_COAXIAL", "MAV_TYPE_HELICOPTER", "MAV_TYPE_AIRSHIP",
           "MAV_TYPE_FREE_BALLOON", "MAV_TYPE_ROCKET", "MAV_TYPE_HEXAROTOR", "MAV_TYPE_OCTOROTOR",
           "MAV_TYPE_TRICOPTER", "MAV_TYPE_FLAPPING_WING", "MAV_TYPE_KITE", "MAV_TYPE_VTOL_*", "MAV_TYPE_PARAFOIL",
           "MAV_TYPE_DODECAROTOR", "MAV_TYPE_DECAROTOR", "MAV_TYPE_GENERIC_MULTIROTOR")


def _types(dialect: Dialect, names: tuple[str, ...]) -> frozenset[int]:
    """MAV_TYPE values of `names` (NAME_* matches a prefix) in the dialect."""
    enum = dialect.enums.get("MAV_TYPE")
    if enum is None:
        return frozenset()
    out = set()
    for value, entry in enum.entries.items():
        for n in names:
            if entry.name == n or (n.endswith("*") and entry.name.startswith(n[:-1])):
                out.add(value)
    return frozenset(out)


class Modes:
    """Mode names for one dialect (the enum lookups done once)."""

    def __init__(self, dialect: Dialect) -> None:
        self.dialect = dialect
        self.ardupilot: dict[int, str] = {}  # MAV_TYPE -> enum name
        for names, enum in _ARDUPILOT_ENUMS:
            if enum in dialect.enums:
                for t in _types(dialect, names):
                    self.ardupilot[t] = enum
        self.aerial = _types(dialect, _AERIAL)
        self.gcs = _types(dialect, ("MAV_TYPE_GCS",))
        self.not_vehicles = _types(dialect, _NOT_VEHICLES)

    def is_vehicle(self, mav_type: int, autopilot: int) -> bool:
        """A HEARTBEAT from a vehicle: an autopilot other than MAV_AUTOPILOT_INVALID, a MAV_TYPE that is not a
        ground station or peripheral (the rule of `mavscope mission`)."""
        return autopilot != MAV_AUTOPILOT_INVALID and mav_type not in self.not_vehicles

    def name(self, autopilot: int, mav_type: int, base_mode: int, custom_mode: int) -> str:
        """The flight mode a HEARTBEAT (or SET_MODE, with the target's autopilot and type) states."""
        if autopilot == MAV_AUTOPILOT_PX4 and base_mode & MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return px4_mode_name((custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF)
        if base_mode & MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            if autopilot == MAV_AUTOPILOT_ARDUPILOTMEGA:
                enum_name = self.ardupilot.get(mav_type)
                enum = self.dialect.enums.get(enum_name) if enum_name else None
                entry = enum.name_of(custom_mode) if enum is not None else None
                if entry is not None and enum_name is not None:
                    return entry.removeprefix(enum_name + "_")
            return f"custom mode {custom_mode}"
        modes = self.dialect.enums.get("MAV_MODE")
        entry = modes.name_of(base_mode) if modes is not None else None
        if entry is not None:
            return entry.removeprefix("MAV_MODE_")
        return f"base mode 0x{base_mode:02x}"

    def command_mode(self, autopilot: int, mav_type: int, params: tuple[float, float, float]) -> str | None:
        """The mode a MAV_CMD_DO_SET_MODE asks for: param1 base mode flags, param2 custom mode (PX4: main
        mode), param3 custom sub mode (PX4). None when the params are not whole numbers."""
        try:
            base, main, sub = (int(p) for p in params)
        except (ValueError, OverflowError):  # NaN or infinite
            return None
        if any(p != int(p) for p in params) or not 0 <= base < 256 or main < 0 or sub < 0:
            return None
        if autopilot == MAV_AUTOPILOT_PX4:
            return px4_mode_name(main, sub) if base & MAV_MODE_FLAG_CUSTOM_MODE_ENABLED else self.name(
                autopilot, mav_type, base, 0)
        return self.name(autopilot, mav_type, base, main & 0xFFFFFFFF)


_last: list[Modes] = []  # the Modes of the Dialect last asked for


def modes_for(dialect: Dialect) -> Modes:
    """The Modes of `dialect`, made once for the Dialect last asked for (every capture of a run shares its
    dialect; a Modes is never changed once made)."""
    if not _last or _last[0].dialect is not dialect:
        _last[:] = [Modes(dialect)]
    return _last[0]


def px4_mode_name(main: int, sub: int) -> str:
    """PX4's main/sub mode as "AUTO.MISSION", "POSCTL.ORBIT", "OFFBOARD" (unknown numbers as numbers)."""
    main_name = PX4_MAIN_MODES.get(main, f"main {main}")
    if main == PX4_MAIN_AUTO:
        return f"AUTO.{PX4_AUTO_SUB_MODES.get(sub, f'sub {sub}')}"
    if main == PX4_MAIN_POSCTL and sub:
        return f"POSCTL.{PX4_POSCTL_SUB_MODES.get(sub, f'sub {sub}')}"
    return main_name


def armed(base_mode: int) -> bool:
    return bool(base_mode & MAV_MODE_FLAG_SAFETY_ARMED)
