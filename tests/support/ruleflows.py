"""Small captures that trigger each rule of the shipped pack (mavscope/rules/pack), and their near misses, built
with pymavlink and written as tlogs (docs/rules.md). What each case builds is its expected answer: the trigger
holds the packet and the vehicle state the rule names (by the rule's references: MAVLink's message and
command definitions, the advisories' values), the near miss differs in the one thing the rule depends on.

A vehicle is 1/1, an ArduCopter (MAV_TYPE_QUADROTOR, MAV_AUTOPILOT_ARDUPILOTMEGA: custom mode 3 is AUTO, 5
LOITER); the ground station 255/190. Frames are 0.1 s apart from T0 (2026-03-14T10:00:00Z).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as v2
from pymavlink.mavftp_op import FTP_OP

from mavscope.analysis.audit_pass import AuditPass
from mavscope.mavlink.dialect import load_dialect
from mavscope.notes import Finding
from mavscope.pipeline.dissect import Anomaly
from mavscope.pipeline.options import PipelineOptions
from mavscope.pipeline.session import open_session
from mavscope.rules import pack_rules
from tests.support.builders import EPOCH_2026, command_long_msg, signer, tlog, vehicle_heartbeat_msg
from tests.support.flows import T0, Sender

VEHICLE, GCS = (1, 1), (255, 190)
AUTO, LOITER = 3, 5  # ArduCopter custom modes
MAV_STATE_STANDBY, MAV_STATE_ACTIVE = 3, 4
ON_GROUND, IN_AIR = 1, 2  # MAV_LANDED_STATE
KEY = bytes(range(32))
FTP_CREATE_DIR, FTP_CREATE, FTP_WRITE, FTP_OPEN_WO = 9, 6, 7, 11
FORCE = 21196  # MAV_CMD_COMPONENT_ARM_DISARM's param2 that skips the checks


class Capture:
    """Frames of several senders (unsigned, or signed with KEY at chosen timestamps), one tlog entry each."""

    def __init__(self) -> None:
        self.senders: dict[tuple[int, int], Sender] = {}
        self.entries: list[tuple[float, bytes]] = []
        self.t = T0

    def send(self, msg: object, src: tuple[int, int] = GCS, *, signed_at: int | None = None) -> int:
        """Add `msg` from `src` (signed with KEY at signature timestamp `signed_at` when given); its record."""
        self.t += 0.1
        if signed_at is not None:
            mav = signer(KEY, *src, timestamp=signed_at)
            frame = bytes(msg.pack(mav))  # type: ignore[attr-defined]
        else:
            frame = self.senders.setdefault(src, Sender(*src)).pack(msg)
        self.entries.append((self.t, frame))
        return len(self.entries)

    def vehicle(self, armed: bool, mode: int = LOITER, in_air: bool | None = None) -> None:
        """The vehicle's HEARTBEAT (MAV_STATE_ACTIVE when armed, STANDBY when not), and its EXTENDED_SYS_STATE
        when `in_air` is given."""
        self.send(vehicle_heartbeat_msg(armed, mode, system_status=MAV_STATE_ACTIVE if armed else MAV_STATE_STANDBY),
                  VEHICLE)
        if in_air is not None:
            self.send(v2.MAVLink_extended_sys_state_message(0, IN_AIR if in_air else ON_GROUND), VEHICLE)

    def command(self, command: int, *params: float) -> int:
        return self.send(command_long_msg(command, *params))

    def ftp(self, opcode: int, path: str, src: tuple[int, int] = GCS, signed_at: int | None = None) -> int:
        data = path.encode()
        op = FTP_OP(0, 0, opcode, len(data), 0, 0, 0, bytearray(data))
        payload = list(bytes(op.pack()).ljust(251, b"\0")[:251])
        return self.send(v2.MAVLink_file_transfer_protocol_message(0, 1, 1, payload), src, signed_at=signed_at)

    def param_set(self, name: str, value: float) -> int:
        return self.send(v2.MAVLink_param_set_message(1, 1, name.encode(), value, 9))

    def write(self, tmp: Path, name: str) -> Path:
        path = tmp / f"{name}.tlog"
        path.write_bytes(tlog(self.entries))
        return path


def _gps_input() -> object:
    return v2.MAVLink_gps_input_message(0, 0, 0, 0, 0, 3, 473_977_420, 85_455_940, 500.0, 1.0, 1.0, 0, 0, 0, 0, 0, 0,
                                        10, 0)


def _hil_gps() -> object:
    return v2.MAVLink_hil_gps_message(0, 3, 473_977_420, 85_455_940, 500_000, 100, 100, 0, 0, 0, 0, 0, 10, 0, 0)


def _waypoints(points: int) -> object:
    z = [0.0] * 5
    return v2.MAVLink_trajectory_representation_waypoints_message(0, points, z, z, z, z, z, z, z, z, z, z, z,
                                                                  [16] * 5)


def _bezier(points: int) -> object:
    z = [0.0] * 5
    return v2.MAVLink_trajectory_representation_bezier_message(0, points, z, z, z, z, z)


def _serial_control(flags: int) -> object:
    data = list(b"ls\n".ljust(70, b"\0"))
    return v2.MAVLink_serial_control_message(10, flags, 0, 0, 3, data)  # SERIAL_CONTROL_DEV_SHELL


Build = Callable[[Capture, bool], None]  # (capture, trigger?): the trigger, or the near miss


def flight_termination(c: Capture, trigger: bool) -> None:
    c.vehicle(True)
    c.command(185, 1.0 if trigger else 0.0)  # MAV_CMD_DO_FLIGHTTERMINATION: param1 > 0.5 terminates


def force_disarm(c: Capture, trigger: bool) -> None:
    c.vehicle(trigger)  # the near miss: the same command to a disarmed vehicle
    c.command(400, 0.0, FORCE)


def reboot_in_flight(c: Capture, trigger: bool) -> None:
    c.vehicle(True, in_air=trigger)  # the near miss: armed on the ground (EXTENDED_SYS_STATE ON_GROUND)
    c.command(246, 1.0)  # MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN: reboot the autopilot


def mission_clear(c: Capture, trigger: bool) -> None:
    c.vehicle(True, AUTO if trigger else LOITER)
    c.send(v2.MAVLink_mission_clear_all_message(1, 1, 0))


def mission_upload(c: Capture, trigger: bool) -> None:
    c.vehicle(trigger, AUTO)  # the near miss: AUTO but disarmed
    c.send(v2.MAVLink_mission_count_message(1, 1, 5, 0))


def log_erase(c: Capture, trigger: bool) -> None:
    c.send(v2.MAVLink_log_erase_message(1, 1) if trigger else v2.MAVLink_log_request_list_message(1, 1, 0, 0xFFFF))


def param(name: str, off: float, on: float) -> Build:
    def build(c: Capture, trigger: bool) -> None:
        c.param_set(name, off if trigger else on)
    return build


def system_id(c: Capture, trigger: bool) -> None:
    if trigger:
        c.param_set("SYSID_THISMAV", 7)
    else:
        c.send(v2.MAVLink_param_request_read_message(1, 1, b"SYSID_THISMAV", -1))  # reading it is no change


def shell(c: Capture, trigger: bool) -> None:
    c.send(_serial_control(0), signed_at=None if trigger else EPOCH_2026)  # the near miss: a signed link


def lua_script(c: Capture, trigger: bool) -> None:
    c.ftp(FTP_CREATE, "APM/scripts/hello.lua", signed_at=None if trigger else EPOCH_2026)


def ftp_write(c: Capture, trigger: bool) -> None:
    c.ftp(FTP_CREATE if trigger else FTP_OPEN_WO, "/fs/microsd/notes.txt" if trigger else "@PARAM/param.pck")


def setup_signing(c: Capture, trigger: bool) -> None:
    if trigger:
        c.send(v2.MAVLink_setup_signing_message(1, 1, list(KEY), EPOCH_2026))
    else:
        c.send(vehicle_heartbeat_msg(False), VEHICLE, signed_at=EPOCH_2026)


def timestamp_ahead(c: Capture, trigger: bool) -> None:
    # two days ahead of the capture clock (the tlog's time T0 + 0.1 s is EPOCH_2026's instant), or 10 s ahead
    c.send(command_long_msg(20), signed_at=EPOCH_2026 + (2 * 86_400 if trigger else 10) * 100_000)


def timestamp_limit(c: Capture, trigger: bool) -> None:
    c.send(command_long_msg(20), signed_at=0xF0000000_0001 if trigger else EPOCH_2026)


def gps_new_source(c: Capture, trigger: bool) -> None:
    c.send(_gps_input(), (1, 220))
    c.send(_gps_input(), (1, 197) if trigger else (1, 220))  # the near miss: the same component goes on


def gps_in_flight(c: Capture, trigger: bool) -> None:
    if trigger:
        c.vehicle(True, in_air=True)
        c.send(_hil_gps(), (1, 197))
    else:  # HIL_GPS from before take-off goes on in the air: not a new source
        c.vehicle(False)
        c.send(_hil_gps(), (1, 197))
        c.vehicle(True, in_air=True)
        c.send(_hil_gps(), (1, 197))


def waypoints(c: Capture, trigger: bool) -> None:
    c.send(_waypoints(6 if trigger else 5))


def bezier(c: Capture, trigger: bool) -> None:
    c.send(_bezier(6 if trigger else 5))


def log_path(c: Capture, trigger: bool) -> None:
    c.ftp(FTP_CREATE_DIR, "/fs/microsd/log/" + ("A" * 70 if trigger else "2026-03-14"))


def mission_param1(c: Capture, trigger: bool) -> None:
    # issue 31902's item: param1 1e+10; the near miss: a waypoint whose param1 is a hold time of 10 s
    c.send(v2.MAVLink_mission_item_int_message(1, 1, 0, 3, 16, 0, 1, 1e10 if trigger else 10.0, 0, 0, 0,
                                               473_977_420, 85_455_940, 50, 0))


def ftp_offset(c: Capture, trigger: bool) -> None:
    # issue 34051's WriteFile at offset 0xFFFFFF12; the near miss: at 1 MiB
    op = FTP_OP(1, 0, FTP_WRITE, 4, 0, 0, 0xFFFFFF12 if trigger else 1 << 20, bytearray(b"AAAA"))
    c.send(v2.MAVLink_file_transfer_protocol_message(0, 1, 1, list(bytes(op.pack()).ljust(251, b"\0")[:251])))


# rule id -> its case (each rule of the shipped pack has one: tests/rules/test_pack.py checks)
CASES: dict[str, Build] = {
    "cmd-flight-termination": flight_termination,
    "cmd-force-disarm-armed": force_disarm,
    "cmd-reboot-in-flight": reboot_in_flight,
    "mission-clear-in-auto": mission_clear,
    "mission-upload-in-auto": mission_upload,
    "log-erase": log_erase,
    "param-arming-checks-off": param("ARMING_CHECK", 0, 1),
    "param-geofence-off": param("FENCE_ENABLE", 0, 1),
    "param-failsafe-off": param("FS_THR_ENABLE", 0, 1),
    "param-system-id-change": system_id,
    "shell-serial-control-unsigned": shell,
    "ftp-lua-script-write-unsigned": lua_script,
    "ftp-file-write-unsigned": ftp_write,
    "signing-setup-in-clear": setup_signing,
    "signing-timestamp-ahead": timestamp_ahead,
    "signing-timestamp-near-limit": timestamp_limit,
    "gps-injection-new-source": gps_new_source,
    "gps-injection-in-flight": gps_in_flight,
    "px4-trajectory-waypoints-overflow": waypoints,
    "px4-trajectory-bezier-overflow": bezier,
    "px4-log-path-overflow": log_path,
    "ardupilot-mission-param1-out-of-range": mission_param1,
    "ardupilot-ftp-offset-wrap": ftp_offset,
}


def write_case(tmp: Path, rule: str, trigger: bool) -> Path:
    c = Capture()
    CASES[rule](c, trigger)
    return c.write(tmp, f"{rule}-{'trigger' if trigger else 'quiet'}")


def pack_findings(path: Path) -> list[Finding]:
    """The rule findings of `audit`'s pass (AuditPass with the story, as `mavscope audit` runs it) over `path`
    with the shipped pack, in its order."""
    dialect = load_dialect([])
    audit = AuditPass(dialect, story=True, rules=pack_rules(dialect))
    with open_session(str(path), PipelineOptions(), dialect=dialect) as session:
        for item in session.items:
            if type(item) is Anomaly:
                audit.anomaly(item)
            else:
                audit.add(item)
    return [f for f in audit.result([])[0] if f.rule is not None]
