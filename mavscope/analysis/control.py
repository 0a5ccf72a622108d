"""Who is in control of each vehicle, and control from anyone else (expert detectors).

The system in control of a vehicle is the first system id that sends it a control message: manual
control (RC_CHANNELS_OVERRIDE, MANUAL_CONTROL), SET_MODE, a command that changes what the vehicle does
(CONTROL_COMMANDS: arming, modes, navigation, mission start, reposition...; not requests for messages or
information, which every ground station sends), offboard setpoints, a mission upload or clear. Control
passes on when the vehicle disarms (the next system to send control takes it). Messages a system sends
to itself, or to a ground station, are not control of a vehicle.

- `second-gcs-control`: a control message from another system id to a vehicle that is armed.
- `unexpected-mode-change`: the vehicle's HEARTBEAT changes to the mode that a mode request (SET_MODE,
  MAV_CMD_DO_SET_MODE) from a system not in control asked for, within MODE_WINDOW_S of the request.
- `unexpected-mission-clear`: MISSION_CLEAR_ALL, or an upload of 0 mission items, from a system that is
  not in control.
- `in-flight-disarm`: an aerial vehicle's HEARTBEAT goes from armed to disarmed while it is in the air:
  EXTENDED_SYS_STATE says IN_AIR or TAKEOFF (seen within STATE_FRESH_S), or, without a landed state, its
  GLOBAL_POSITION_INT.relative_alt was above ALT_FLYING_M.

Several ground stations asking a vehicle for data (QGroundControl, Mission Planner and MAVProxy side by
side) is normal and not control. Bounded: MAX_SENDERS vehicles and (vehicle, sender) pairs.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from mavscope.analysis.framelist import frame_numbers
from mavscope.analysis.vehicles import MAX_SENDERS, Heartbeat, Systems
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.notes import Finding, FrameNumbers, finding

Fields = dict[str, object]

# MAV_CMD names that change what a vehicle does (resolved in the dialect; missing names are skipped).
CONTROL_COMMAND_NAMES = (
    "MAV_CMD_COMPONENT_ARM_DISARM", "MAV_CMD_DO_SET_MODE", "MAV_CMD_NAV_WAYPOINT", "MAV_CMD_NAV_LOITER_UNLIM",
    "MAV_CMD_NAV_LOITER_TURNS", "MAV_CMD_NAV_LOITER_TIME", "MAV_CMD_NAV_RETURN_TO_LAUNCH", "MAV_CMD_NAV_LAND",
    "MAV_CMD_NAV_TAKEOFF", "MAV_CMD_NAV_LAND_LOCAL", "MAV_CMD_NAV_TAKEOFF_LOCAL", "MAV_CMD_NAV_VTOL_TAKEOFF",
    "MAV_CMD_NAV_VTOL_LAND", "MAV_CMD_NAV_GUIDED_ENABLE", "MAV_CMD_DO_REPOSITION", "MAV_CMD_DO_PAUSE_CONTINUE",
    "MAV_CMD_DO_CHANGE_SPEED", "MAV_CMD_DO_CHANGE_ALTITUDE", "MAV_CMD_DO_SET_HOME", "MAV_CMD_DO_JUMP",
    "MAV_CMD_DO_SET_MISSION_CURRENT", "MAV_CMD_DO_LAND_START", "MAV_CMD_DO_GO_AROUND", "MAV_CMD_DO_ORBIT",
    "MAV_CMD_DO_FLIGHTTERMINATION", "MAV_CMD_DO_PARACHUTE", "MAV_CMD_DO_MOTOR_TEST", "MAV_CMD_DO_SET_SERVO",
    "MAV_CMD_DO_REPEAT_SERVO", "MAV_CMD_DO_FENCE_ENABLE", "MAV_CMD_DO_GUIDED_LIMITS", "MAV_CMD_MISSION_START",
    "MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN", "MAV_CMD_DO_VTOL_TRANSITION", "MAV_CMD_NAV_FOLLOW",
    "MAV_CMD_DO_FOLLOW", "MAV_CMD_DO_FOLLOW_REPOSITION", "MAV_CMD_OVERRIDE_GOTO", "MAV_CMD_DO_SET_REVERSE",
)
MANUAL = frozenset({"RC_CHANNELS_OVERRIDE", "MANUAL_CONTROL"})
OFFBOARD = frozenset({"SET_POSITION_TARGET_LOCAL_NED", "SET_POSITION_TARGET_GLOBAL_INT", "SET_ATTITUDE_TARGET"})
WANTS = MANUAL | OFFBOARD | {"HEARTBEAT", "SET_MODE", "COMMAND_LONG", "COMMAND_INT", "MISSION_CLEAR_ALL",
                             "MISSION_COUNT", "EXTENDED_SYS_STATE", "GLOBAL_POSITION_INT"}
MODE_WINDOW_S = 3.0
STATE_FRESH_S = 5.0
ALT_FLYING_M = 10.0
MAV_MISSION_TYPE_MISSION, MAV_MISSION_TYPE_ALL = 0, 255
MAV_LANDED_STATE_IN_AIR, MAV_LANDED_STATE_TAKEOFF = 2, 3
MAV_LANDED_STATE_UNDEFINED = 0
MAV_CMD_DO_SET_MODE, MAV_CMD_COMPONENT_ARM_DISARM = 176, 400


@dataclass
class _Control:
    """One vehicle's control: who holds it, since which frame, the last mode request from someone else."""

    holder: int | None = None
    since: int = 0
    # (sender, message, frame, time, mode asked for) of the last mode request from a system not in control
    request: tuple[int, str, int, float | None, str] | None = None
    landed: tuple[int, float | None] | None = None  # (MAV_LANDED_STATE, capture time)
    alt: tuple[float, float | None] | None = None  # (relative altitude m, capture time)
    disarm: tuple[int, int, float | None] | None = None  # (sender, frame, time) of the last disarm command
    armed: bool = False
    mode: str = ""


@dataclass
class _Intrusions:
    frames: FrameNumbers = field(default_factory=frame_numbers)
    messages: dict[str, int] = field(default_factory=dict)
    holder: int = 0
    since: int = 0


def _target(name: str, fields: Fields) -> int | None:
    t = fields.get("target" if name == "MANUAL_CONTROL" else "target_system")
    return t if isinstance(t, int) else None


class ControlSources:
    """Control of each vehicle and control by others (see the module docstring)."""

    wants = WANTS
    clean: frozenset[str | int] = WANTS  # what `add` reads (see expert.Detector)
    notes: frozenset[str] = frozenset()  # it reads its messages alone, whatever their notes

    def __init__(self, dialect: Dialect) -> None:
        self.dialect = dialect
        self.systems = Systems(dialect)
        cmds = dialect.enums.get("MAV_CMD")
        self.control_commands = frozenset(cmds.by_name[n].value for n in CONTROL_COMMAND_NAMES
                                          if cmds is not None and n in cmds.by_name)
        self.vehicles: dict[int, _Control] = {}
        self.intrusions: dict[tuple[int, int], _Intrusions] = {}  # (vehicle, sender) -> control while armed
        self.out: list[Finding] = []

    def _vehicle(self, sysid: int) -> _Control | None:
        c = self.vehicles.get(sysid)
        if c is None and len(self.vehicles) < MAX_SENDERS:
            c = self.vehicles[sysid] = _Control()
        return c

    def add(self, f: Frame, fields: Fields | None) -> None:
        md = f.msgdef
        if fields is None or md is None or md.name not in WANTS:
            return
        name = md.name
        if name == "HEARTBEAT":
            self._heartbeat(f, fields)
            return
        if name == "EXTENDED_SYS_STATE" or name == "GLOBAL_POSITION_INT":
            c = self.vehicles.get(f.sysid) if f.sysid in self.systems.vehicles else None
            if c is not None and name == "EXTENDED_SYS_STATE" and isinstance(fields.get("landed_state"), int):
                c.landed = (int(fields["landed_state"]), f.time)  # type: ignore[call-overload]
            elif c is not None and isinstance(fields.get("relative_alt"), int):
                c.alt = (int(fields["relative_alt"]) / 1000, f.time)  # type: ignore[call-overload]
            return
        target = _target(name, fields)
        if target is None or target == f.sysid or target in self.systems.gcs:
            return
        targets = [target] if target else [v for v in self.systems.vehicles if v != f.sysid]
        for v in targets:
            self._control(f, name, fields, v)

    def _control(self, f: Frame, name: str, fields: Fields, vehicle: int) -> None:
        command = fields.get("command") if name in ("COMMAND_LONG", "COMMAND_INT") else None
        if command is not None and command not in self.control_commands:
            return
        mtype = fields.get("mission_type", MAV_MISSION_TYPE_MISSION)
        clear = (name == "MISSION_CLEAR_ALL" and mtype in (MAV_MISSION_TYPE_MISSION, MAV_MISSION_TYPE_ALL)) or \
                (name == "MISSION_COUNT" and fields.get("count") == 0 and mtype == MAV_MISSION_TYPE_MISSION)
        if name == "MISSION_COUNT" and self.systems.is_vehicle((f.sysid, f.compid)):
            return  # a vehicle sending its mission (a download) controls nothing
        c = self._vehicle(vehicle)
        if c is None:
            return
        label = name if command is None else self._command_name(int(command))
        if command == MAV_CMD_COMPONENT_ARM_DISARM and fields.get("param1") == 0:
            c.disarm = (f.sysid, f.record, f.time)
        if c.holder is None:
            c.holder, c.since = f.sysid, f.record
            return
        if c.holder == f.sysid:
            return
        asked = self._asked(vehicle, name, fields) if name == "SET_MODE" or command == MAV_CMD_DO_SET_MODE else None
        if asked is not None:
            c.request = (f.sysid, label, f.record, f.time, asked)
        if clear:
            self.out.append(mission_clear(f.sysid, vehicle, name == "MISSION_CLEAR_ALL", f.record, c.holder, c.since))
        if c.armed:
            key = (vehicle, f.sysid)
            intr = self.intrusions.get(key)
            if intr is None:
                if len(self.intrusions) >= MAX_SENDERS:
                    return
                intr = self.intrusions[key] = _Intrusions(holder=c.holder, since=c.since)
            intr.frames.add(f.record)
            intr.messages[label] = intr.messages.get(label, 0) + 1

    def _asked(self, vehicle: int, name: str, fields: Fields) -> str | None:
        """The mode a SET_MODE or DO_SET_MODE asks `vehicle` for, named as its HEARTBEAT would name it."""
        hb = self.systems.vehicle(vehicle)
        autopilot, mav_type = (hb.autopilot, hb.type) if hb is not None else (0, 0)
        if name == "SET_MODE":
            base, custom = fields.get("base_mode"), fields.get("custom_mode")
            if not isinstance(base, int) or not isinstance(custom, int):
                return None
            return self.systems.modes.name(autopilot, mav_type, base, custom)
        params = [fields.get(p) for p in ("param1", "param2", "param3")]
        if not all(isinstance(p, (int, float)) for p in params):
            return None
        return self.systems.modes.command_mode(autopilot, mav_type, tuple(params))  # type: ignore[arg-type]

    def _command_name(self, command: int) -> str:
        cmds = self.dialect.enums.get("MAV_CMD")
        name = cmds.name_of(command) if cmds is not None else None
        return (name or f"command {command}").removeprefix("MAV_CMD_")

    def _heartbeat(self, f: Frame, fields: Fields) -> None:
        hb = self.systems.see(f, fields)
        if hb is None or self.systems.vehicles.get(f.sysid) != (f.sysid, f.compid):
            return
        c = self._vehicle(f.sysid)
        if c is None:
            return
        mode = self.systems.mode_name(hb)
        req = c.request
        if req is not None and req[3] is not None and f.time is not None and f.time - req[3] > MODE_WINDOW_S:
            req = c.request = None  # not followed in time
        if c.mode and mode != c.mode and req is not None and mode == req[4]:
            if c.holder is not None and req[0] != c.holder:
                self.out.append(mode_change(f.sysid, c.mode, mode, f.record, req[1], req[0], req[2], c.holder))
            c.request = None
        if c.armed and not hb.armed:
            self._disarmed(f, c, hb)
            c.holder = None  # control passes on after a disarm
        c.armed, c.mode = hb.armed, mode

    def _disarmed(self, f: Frame, c: _Control, hb: Heartbeat) -> None:
        if hb.type not in self.systems.modes.aerial:
            return
        why = None

        def fresh(t: float | None) -> bool:
            return t is None or f.time is None or 0 <= f.time - t <= STATE_FRESH_S

        if c.landed is not None and c.landed[0] != MAV_LANDED_STATE_UNDEFINED and fresh(c.landed[1]):
            if c.landed[0] in (MAV_LANDED_STATE_IN_AIR, MAV_LANDED_STATE_TAKEOFF):
                why = landed_why(c.landed[0])
        elif c.alt is not None and c.alt[0] > ALT_FLYING_M and fresh(c.alt[1]):
            why = altitude_why(c.alt[0])
        if why is None:
            return
        by = c.disarm[:2] if c.disarm is not None and fresh(c.disarm[2]) else None
        self.out.append(in_flight_disarm(f.sysid, why, f.record, by))

    def findings(self) -> list[Finding]:
        out = list(self.out)
        for (vehicle, sender), intr in self.intrusions.items():
            kinds = ", ".join(f"{n} {k}" for n, k in sorted(intr.messages.items(), key=lambda x: -x[1]))
            out.append(finding("second-gcs-control",
                               f"system {sender} sends control to armed vehicle {vehicle} while system {intr.holder} "
                               f"is in control (since frame {intr.since}): {intr.frames.count} frame(s) ({kinds})",
                               intr.frames.nums))
        return out


# ControlSources' findings
def mission_clear(sender: int, vehicle: int, clear_all: bool, record: int, holder: int, since: int) -> Finding:
    what = "MISSION_CLEAR_ALL" if clear_all else "an upload of 0 mission items"
    return finding("unexpected-mission-clear", f"system {sender} clears the mission of vehicle {vehicle} ({what}, "
                                               f"frame {record}) while system {holder} is in control (since frame "
                                               f"{since})", (record,))


def mode_change(vehicle: int, old: str, new: str, record: int, label: str, sender: int, asked: int,
                holder: int) -> Finding:
    return finding("unexpected-mode-change",
                   f"vehicle {vehicle} changes mode {old} -> {new} (frame {record}) as {label} from system {sender} "
                   f"(frame {asked}) asked, while system {holder} is in control", (asked, record))


def landed_why(state: int) -> str:
    return f"EXTENDED_SYS_STATE says {'IN_AIR' if state == MAV_LANDED_STATE_IN_AIR else 'TAKEOFF'}"


def altitude_why(alt: float) -> str:
    return f"{alt:.1f} m above home"


def in_flight_disarm(vehicle: int, why: str, record: int, by: tuple[int, int] | None) -> Finding:
    """`by`: (system, frame) of the disarm command, when one came shortly before."""
    more = "" if by is None else f"; the disarm command came from system {by[0]} (frame {by[1]})"
    frames = [record] if by is None else [by[1], record]
    return finding("in-flight-disarm", f"vehicle {vehicle} disarmed in the air ({why}) at frame {record}{more}",
                   frames)
