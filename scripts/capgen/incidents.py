"""Two incidents, each with a truth file written from what was sent (never by decoding it):

- `gcs_takeover.pcap`: a PX4 quadrotor flies a mission for its ground station (255/190); in flight a second
  ground station (sysid 42, another UDP port) switches it to hold, then to position control, steers it with
  MANUAL_CONTROL, clears its mission and force-disarms it at 25 m.
- `gps_spoof.pcap`: an ArduCopter flying north is jammed (GNSS fix and satellites collapse for 4 s), then
  spoofed: the GPS position jumps 700 m east while the reported velocity stays 8 m/s, the EKF flags a GPS
  glitch and then resets onto the false position, the vehicle's EKF failsafe lands it, and the GNSS time
  steps an hour ahead.

Each scripted message carries a tag; after packing (in time order, one frame per datagram) the truth gives
the record numbers of the tagged messages and the vehicle states the generator put in its HEARTBEATs.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from random import Random
from typing import Any

import pymavlink.dialects.v20.ardupilotmega as apm
import pymavlink.dialects.v20.common as mav2

from .analysis import mission_item
from .constants import (
    BASE_TIME_US,
    GCS_COMPID,
    GCS_SYSID,
    GCS_UDP_PORT,
    HOME_ALT_M,
    LINKTYPE_ETHERNET,
    LOOPBACK_V4,
    MAV_AUTOPILOT_ARDUPILOTMEGA,
    MAV_AUTOPILOT_PX4,
    MAV_CMD_COMPONENT_ARM_DISARM,
    MAV_CMD_NAV_RETURN_TO_LAUNCH,
    MAV_CMD_NAV_TAKEOFF,
    MAV_CMD_NAV_WAYPOINT,
    MAV_MISSION_ACCEPTED,
    MAV_MISSION_TYPE_MISSION,
    MAV_MODE_FLAG_AUTO_ENABLED,
    MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
    MAV_MODE_FLAG_GUIDED_ENABLED,
    MAV_MODE_FLAG_MANUAL_INPUT_ENABLED,
    MAV_MODE_FLAG_SAFETY_ARMED,
    MAV_MODE_FLAG_STABILIZE_ENABLED,
    MAV_RESULT_ACCEPTED,
    MAV_SEVERITY_INFO,
    MAV_SEVERITY_WARNING,
    MAV_TYPE_QUADROTOR,
    VEHICLE_BOOT_OFFSET_MS,
    VEHICLE_COMPID,
    VEHICLE_SYSID,
    VEHICLE_UDP_PORT,
    VEHICLE_UTC_OFFSET_US,
)
from .frames import Endpoint, Send
from .packets import UdpFlow
from .story import to_degE7
from .summary import summarize_packets
from .telemetry import gcs_heartbeat
from .writers import write_pcap

MAV_CMD_DO_SET_MODE = 176
FORCE_DISARM = 21_196.0
MAV_SEVERITY_EMERGENCY, MAV_SEVERITY_CRITICAL = 0, 2
MAV_STATE_STANDBY, MAV_STATE_ACTIVE, MAV_STATE_CRITICAL = 3, 4, 5
ON_GROUND, IN_AIR, TAKEOFF, LANDING = 1, 2, 3, 4  # MAV_LANDED_STATE
GPS_FIX_TYPE_NO_FIX, GPS_FIX_TYPE_3D_FIX = 1, 3
INTRUDER_SYSID, INTRUDER_COMPID, INTRUDER_UDP_PORT = 42, 190, 14_551

# PX4 custom modes (px4_custom_mode.h: custom_mode = sub << 24 | main << 16; main AUTO 4 with sub LOITER 3,
# MISSION 4, RTL 5; main POSCTL 3), named as mavros and QGroundControl name them.
PX4 = {"AUTO.LOITER": (4, 3), "AUTO.MISSION": (4, 4), "AUTO.RTL": (4, 5), "POSCTL": (3, 0)}
# ArduCopter mode numbers (ArduCopter/mode.h, the Copter flight-mode documentation).
COPTER = {"LOITER": 5, "AUTO": 3, "LAND": 9}

Build = Callable[[Any], Any]  # mav -> message


@dataclass(frozen=True)
class Phase:
    """The vehicle's state from time `t` (s) on."""

    t: float
    mode: str
    armed: bool
    landed: int  # MAV_LANDED_STATE
    status: int  # MAV_STATE


def phase_at(phases: Sequence[Phase], t: float) -> Phase:
    current = phases[0]
    for p in phases:
        if p.t <= t:
            current = p
    return current


def along(keys: Sequence[tuple[float, float, float, float]], t: float) -> tuple[float, float, float, float, float,
                                                                              float]:
    """(north, east, alt, v_north, v_east, v_down) on straight legs between keyframes (t, north, east, alt)."""
    a, b = keys[0], keys[-1]
    if t < a[0]:
        b = a
    for k0, k1 in zip(keys, keys[1:]):
        if k0[0] <= t < k1[0]:
            a, b = k0, k1
            break
    else:
        if t >= keys[-1][0]:
            a = b = keys[-1]
    span = b[0] - a[0]
    f = (t - a[0]) / span if span > 0 else 0.0
    pos = [a[i] + (b[i] - a[i]) * f for i in (1, 2, 3)]
    vel = [(b[i] - a[i]) / span for i in (1, 2, 3)] if span > 0 else [0.0, 0.0, 0.0]
    return pos[0], pos[1], pos[2], vel[0], vel[1], -vel[2]


class Script:
    """Messages to send, each at a time from a side, optionally tagged for the truth."""

    def __init__(self) -> None:
        self.entries: list[tuple[int, int, str, Build, str | None]] = []

    def add(self, t: float, side: str, build: Build, tag: str | None = None) -> None:
        self.entries.append((round(t * 1_000_000), len(self.entries), side, build, tag))

    def pack(self, endpoints: dict[str, Endpoint]) -> tuple[list[Send], dict[str, list[int]]]:
        """Pack in time order; returns the sends and, per tag, the record numbers (one datagram each)."""
        sends, tags = [], {}
        for number, (t_us, _, side, build, tag) in enumerate(sorted(self.entries, key=lambda e: (e[0], e[1])), 1):
            ep = endpoints[side]
            sends.append(Send(t_us, side, [ep.pack(build(ep.mav), BASE_TIME_US + t_us)]))
            if tag is not None:
                tags.setdefault(tag, []).append(number)
        return sends, tags


def _pcap(outdir: Path, name: str, sends: list[Send], flows: dict[str, UdpFlow]) -> dict[str, Any]:
    """One datagram per send, through the flow of the side that sends it (or receives it, for the vehicle)."""
    pkts = []
    for s in sends:
        side, peer = s.side.partition(">")[::2]
        flow = flows[peer or side]
        pkts.append(flow.packet(Send(s.t_us, "vehicle" if side == "vehicle" else "gcs", s.frames)))
    offsets = write_pcap(outdir / name, LINKTYPE_ETHERNET, pkts)
    return summarize_packets("pcap", [LINKTYPE_ETHERNET], pkts, offsets)


def write_truth(outdir: Path, name: str, truth: dict[str, Any]) -> str:
    """`<capture>.truth.json` beside the capture; returns its file name."""
    path = outdir / (name.rsplit(".", 1)[0] + ".truth.json")
    path.write_text(json.dumps(truth, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    return path.name


def _heartbeat_changes(tags: dict[str, list[int]], beats: list[tuple[float, Phase]], mode_names: bool = True
                       ) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """The arming and mode changes the vehicle's HEARTBEATs show, with the record of the first HEARTBEAT
    that shows each (tag "hb" lists every vehicle HEARTBEAT in time order)."""
    arming, modes = [], []
    prev: Phase | None = None
    for record, (t, ph) in zip(tags["hb"], beats):
        if prev is not None and ph.armed != prev.armed:
            arming.append({"record": record, "armed": ph.armed, "mode": ph.mode})
        if prev is not None and ph.mode != prev.mode:
            modes.append({"record": record, "from": prev.mode, "to": ph.mode})
        prev = ph
    return arming, modes


# --- gcs_takeover.pcap ------------------------------------------------------------------------------

TAKEOVER_KEYS = ((0, 0, 0, 0), (9.5, 0, 0, 0), (12.5, 0, 0, 20), (20.5, 60, 0, 20), (28.5, 60, 40, 20),
                 (30.5, 60, 40, 20), (33.5, 60, 55, 25), (34.5, 55, 50, 25), (40.0, 55, 77.5, 25),
                 (42.3, 55, 77.5, 0), (60, 55, 77.5, 0))
TAKEOVER_PHASES = (
    Phase(0.0, "AUTO.LOITER", False, ON_GROUND, MAV_STATE_STANDBY),
    Phase(8.05, "AUTO.LOITER", True, ON_GROUND, MAV_STATE_ACTIVE),
    Phase(9.05, "AUTO.MISSION", True, TAKEOFF, MAV_STATE_ACTIVE),
    Phase(12.5, "AUTO.MISSION", True, IN_AIR, MAV_STATE_ACTIVE),
    Phase(28.05, "AUTO.LOITER", True, IN_AIR, MAV_STATE_ACTIVE),
    Phase(30.05, "POSCTL", True, IN_AIR, MAV_STATE_ACTIVE),
    Phase(33.05, "AUTO.RTL", True, IN_AIR, MAV_STATE_ACTIVE),
    Phase(34.05, "POSCTL", True, IN_AIR, MAV_STATE_ACTIVE),
    Phase(40.05, "POSCTL", False, IN_AIR, MAV_STATE_CRITICAL),
    Phase(42.3, "POSCTL", False, ON_GROUND, MAV_STATE_CRITICAL),
)


def _px4_mode(name: str) -> int:
    main, sub = PX4[name]
    return sub << 24 | main << 16


def _px4_heartbeat(ph: Phase) -> Build:
    base = MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | MAV_MODE_FLAG_STABILIZE_ENABLED
    base |= MAV_MODE_FLAG_MANUAL_INPUT_ENABLED if ph.mode == "POSCTL" else \
        MAV_MODE_FLAG_GUIDED_ENABLED | MAV_MODE_FLAG_AUTO_ENABLED
    if ph.armed:
        base |= MAV_MODE_FLAG_SAFETY_ARMED
    mode = _px4_mode(ph.mode)
    return lambda mav: mav.heartbeat_encode(MAV_TYPE_QUADROTOR, MAV_AUTOPILOT_PX4, base, mode, ph.status, 3)


def _telemetry(script: Script, duration: int, keys: Sequence[tuple[float, float, float, float]],
               phases: Sequence[Phase], heartbeat: Callable[[Phase], Build], gps_hz: int, gps_boot_clock: bool,
               utc_jump: tuple[float, int] | None = None,
               gps_offset: Callable[[float], tuple[float, float]] | None = None,
               ekf_offset_from: float | None = None) -> list[tuple[float, Phase]]:
    """The vehicle's periodic messages; returns (time, phase) of every HEARTBEAT, in time order."""
    beats = []

    def boot_ms(t: float) -> int:
        return round(t * 1000) + VEHICLE_BOOT_OFFSET_MS

    for sec in range(duration):
        t = sec + 0.001
        ph = phase_at(phases, t)
        beats.append((t, ph))
        script.add(t, "vehicle", heartbeat(ph), "hb")
        utc = BASE_TIME_US + round((sec + 0.5) * 1_000_000) + VEHICLE_UTC_OFFSET_US
        if utc_jump is not None and sec + 0.5 >= utc_jump[0]:
            utc += utc_jump[1]
        script.add(sec + 0.5, "vehicle", lambda mav, u=utc, b=boot_ms(sec + 0.5): mav.system_time_encode(u, b),
                   "system_time")
        script.add(sec + 0.6, "vehicle", lambda mav, ph=phase_at(phases, sec + 0.6): mav.extended_sys_state_encode(
            0, ph.landed))
    for tick in range(duration * 5):  # GLOBAL_POSITION_INT at 5 Hz
        t = tick / 5 + 0.02
        n, e, alt, vn, ve, vd = along(keys, t)
        if ekf_offset_from is not None and gps_offset is not None and t >= ekf_offset_from:
            dn, de = gps_offset(t)
            n, e = n + dn, e + de
        lat, lon = to_degE7(n, e)
        script.add(t, "vehicle", lambda mav, t=t, lat=lat, lon=lon, alt=alt, vn=vn, ve=ve, vd=vd:
                   mav.global_position_int_encode(boot_ms(t), lat, lon, round((HOME_ALT_M + alt) * 1000),
                                                  round(alt * 1000), round(vn * 100), round(ve * 100),
                                                  round(vd * 100), 0), "gpi")
    for tick in range(duration * gps_hz):
        t = tick / gps_hz + 0.05
        n, e, alt, vn, ve, _ = along(keys, t)
        if gps_offset is not None:
            dn, de = gps_offset(t)
            n, e = n + dn, e + de
        lat, lon = to_degE7(n, e)
        fix, sats = GPS_FIX_TYPE_3D_FIX, 16
        if gps_offset is not None and 20.0 <= t < 24.0:  # jammed
            fix, sats = GPS_FIX_TYPE_NO_FIX, 3
        elif gps_offset is not None and t >= 24.0:  # the spoofer's strong signals
            sats = 19
        speed = (vn * vn + ve * ve) ** 0.5
        stamp = round(t * 1_000_000) + VEHICLE_BOOT_OFFSET_MS * 1000 if gps_boot_clock else \
            BASE_TIME_US + round(t * 1_000_000) + VEHICLE_UTC_OFFSET_US
        script.add(t, "vehicle", lambda mav, s=stamp, fx=fix, lat=lat, lon=lon, alt=alt, v=speed, n=sats:
                   mav.gps_raw_int_encode(s, fx, lat, lon, round((HOME_ALT_M + alt) * 1000), 90, 140,
                                          round(v * 100), 0, n), "gps")
    return beats


def gcs_takeover(outdir: Path) -> dict[str, Any]:
    rng = Random(21)
    script = Script()
    veh, gcs = (VEHICLE_SYSID, VEHICLE_COMPID), (GCS_SYSID, GCS_COMPID)
    intruder = (INTRUDER_SYSID, INTRUDER_COMPID)
    beats = _telemetry(script, 60, TAKEOVER_KEYS, TAKEOVER_PHASES, _px4_heartbeat, 1, False)
    for sec in range(60):
        script.add(sec + 0.5 + rng.randint(0, 900) / 1e6, "gcs", lambda mav: gcs_heartbeat(mav, None, 0))
    for sec in range(27, 42):
        script.add(sec + 0.3 + rng.randint(0, 900) / 1e6, "intruder", lambda mav: gcs_heartbeat(mav, None, 0))
    for sec, cur in ((s, 0 if s < 13 or s >= 38 else 1 if s < 21 else 2) for s in range(60)):
        script.add(sec + 0.7, "vehicle", lambda mav, c=cur: mav.mission_current_encode(c, 4), "mission_current")
    script.add(12.55, "vehicle", lambda mav: mav.mission_item_reached_encode(0), "reached")
    script.add(20.55, "vehicle", lambda mav: mav.mission_item_reached_encode(1), "reached")
    home, wp1, wp2 = to_degE7(0, 0), to_degE7(60, 0), to_degE7(60, 60)
    items = [mission_item(0, MAV_CMD_NAV_TAKEOFF, *home, 20.0), mission_item(1, MAV_CMD_NAV_WAYPOINT, *wp1, 20.0),
             mission_item(2, MAV_CMD_NAV_WAYPOINT, *wp2, 20.0),
             mission_item(3, MAV_CMD_NAV_RETURN_TO_LAUNCH, 0, 0, 0.0)]
    t = 3.0
    script.add(t, "gcs", lambda mav: mav.mission_count_encode(*veh, 4, MAV_MISSION_TYPE_MISSION), "upload")
    for seq, item in enumerate(items):
        script.add(t + 0.01 + seq * 0.02, "vehicle>gcs", lambda mav, q=seq: mav.mission_request_int_encode(
            *gcs, q, MAV_MISSION_TYPE_MISSION))
        script.add(t + 0.02 + seq * 0.02, "gcs", item)
    script.add(t + 0.1, "vehicle>gcs", lambda mav: mav.mission_ack_encode(*gcs, MAV_MISSION_ACCEPTED,
                                                                          MAV_MISSION_TYPE_MISSION))
    commands: list[dict[str, Any]] = []

    def command(at: float, side: str, who: tuple[int, int], cmd: int, *params: float, mode: str | None = None) -> None:
        p = list(params) + [0.0] * (7 - len(params))
        tag = f"cmd{len(commands)}"
        script.add(at, side, lambda mav: mav.command_long_encode(*veh, cmd, 0, *p), tag)
        script.add(at + 0.012, f"vehicle>{side}", lambda mav: mav.command_ack_encode(
            cmd, MAV_RESULT_ACCEPTED, 0, 0, *who), tag + "ack")
        commands.append({"tag": tag, "from": list(who), "command": cmd, "params": p[:3], "result": MAV_RESULT_ACCEPTED,
                         "mode": mode})

    def set_mode(at: float, name: str) -> None:
        script.add(at, "intruder", lambda mav: mav.set_mode_encode(
            VEHICLE_SYSID, MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, _px4_mode(name)), "intruder_control")

    command(8.0, "gcs", gcs, MAV_CMD_COMPONENT_ARM_DISARM, 1.0)
    command(9.0, "gcs", gcs, MAV_CMD_DO_SET_MODE, 1.0, *PX4["AUTO.MISSION"], mode="AUTO.MISSION")
    command(28.0, "intruder", intruder, MAV_CMD_DO_SET_MODE, 1.0, *PX4["AUTO.LOITER"], mode="AUTO.LOITER")
    set_mode(30.0, "POSCTL")
    for k in range(15):
        script.add(30.2 + k * 0.2, "intruder", lambda mav: mav.manual_control_encode(VEHICLE_SYSID, 0, 500, 600, 0, 0),
                   "intruder_control")
    command(33.0, "gcs", gcs, MAV_CMD_NAV_RETURN_TO_LAUNCH)
    set_mode(34.0, "POSCTL")
    for k in range(29):
        script.add(34.2 + k * 0.2, "intruder", lambda mav: mav.manual_control_encode(VEHICLE_SYSID, 0, 500, 500, 0, 0),
                   "intruder_control")
    script.add(37.0, "intruder", lambda mav: mav.mission_clear_all_encode(*veh, MAV_MISSION_TYPE_MISSION), "clear")
    script.add(37.01, "vehicle>intruder", lambda mav: mav.mission_ack_encode(*intruder, MAV_MISSION_ACCEPTED,
                                                                             MAV_MISSION_TYPE_MISSION))
    command(40.0, "intruder", intruder, MAV_CMD_COMPONENT_ARM_DISARM, 0.0, FORCE_DISARM)
    for at, sev, text in ((8.1, MAV_SEVERITY_INFO, "Armed by external command"),
                          (12.6, MAV_SEVERITY_INFO, "Takeoff detected"),
                          (40.1, MAV_SEVERITY_CRITICAL, "Disarmed by external command"),
                          (42.4, MAV_SEVERITY_EMERGENCY, "Crash detected")):
        script.add(at, "vehicle", lambda mav, s=sev, x=text: mav.statustext_encode(s, x.encode()), "statustext")

    endpoints = {"vehicle": Endpoint(mav2, *veh), "gcs": Endpoint(mav2, *gcs), "intruder": Endpoint(mav2, *intruder)}
    for side in ("vehicle>gcs", "vehicle>intruder"):
        endpoints[side] = endpoints["vehicle"]
    sends, tags = script.pack(endpoints)
    flows = {"gcs": UdpFlow({"vehicle": (LOOPBACK_V4, VEHICLE_UDP_PORT), "gcs": (LOOPBACK_V4, GCS_UDP_PORT)}, rng),
             "intruder": UdpFlow({"vehicle": (LOOPBACK_V4, VEHICLE_UDP_PORT),
                                  "gcs": (LOOPBACK_V4, INTRUDER_UDP_PORT)}, rng)}
    flows["vehicle"] = flows["gcs"]
    summary = _pcap(outdir, "gcs_takeover.pcap", sends, flows)
    arming, modes = _heartbeat_changes(tags, beats)
    for c in commands:
        c["record"], c["ack_record"] = tags[c["tag"]][0], tags[c["tag"] + "ack"][0]
    control = sorted(tags["intruder_control"] + [c["record"] for c in commands if c["from"] == list(intruder)]
                     + tags["clear"])
    armed_until = next(a["record"] for a in arming if not a["armed"])
    truth = {
        "vehicle": list(veh), "gcs": list(gcs), "intruder": list(intruder),
        "intruder_udp_port": INTRUDER_UDP_PORT, "autopilot": "PX4",
        "arming": arming, "modes": modes,
        "commands": [{k: v for k, v in c.items() if k != "tag"} for c in commands],
        "mission_upload_record": tags["upload"][0],
        "mission_items_reached": [[r, seq] for r, seq in zip(tags["reached"], (0, 1))],
        "statustext_records": tags["statustext"],
        "intruder_control_records": control,
        "mission_clear_record": tags["clear"][0],
        "disarm_in_air": {"command_record": commands[-1]["record"], "heartbeat_record": armed_until,
                          "relative_alt_m": 25.0},
        "findings": {
            "second-gcs-control": [control],
            "unexpected-mode-change": [[c["record"], m["record"]] for c, m in zip(
                [commands[2], {"record": tags["intruder_control"][0]}, {"record": tags["intruder_control"][16]}],
                [m for m in modes if m["to"] in ("AUTO.LOITER", "POSCTL")])],
            "unexpected-mission-clear": [[tags["clear"][0]]],
            "in-flight-disarm": [[commands[-1]["record"], armed_until]],
        },
    }
    summary["truth_file"] = write_truth(outdir, "gcs_takeover.pcap", truth)
    return summary


# --- gps_spoof.pcap ---------------------------------------------------------------------------------

SPOOF_KEYS = ((0, 0, 0, 0), (6, 0, 0, 0), (9, 0, 0, 30), (32, 184, 0, 30), (47, 184, 0, 0), (60, 184, 0, 0))
SPOOF_PHASES = (
    Phase(0.0, "LOITER", False, ON_GROUND, MAV_STATE_STANDBY),
    Phase(5.05, "LOITER", True, ON_GROUND, MAV_STATE_ACTIVE),
    Phase(6.05, "AUTO", True, TAKEOFF, MAV_STATE_ACTIVE),
    Phase(9.0, "AUTO", True, IN_AIR, MAV_STATE_ACTIVE),
    Phase(32.0, "LAND", True, LANDING, MAV_STATE_CRITICAL),
    Phase(47.0, "LAND", True, ON_GROUND, MAV_STATE_CRITICAL),
    Phase(47.5, "LAND", False, ON_GROUND, MAV_STATE_STANDBY),
)
SPOOF_JUMP_EAST_M = 700.0
SPOOF_AT, EKF_RESET_AT, TIME_JUMP_AT, TIME_JUMP_US = 30.0, 31.0, 40.0, 3_600_000_000
HEALTHY_EKF = 0x33F  # attitude, velocities, positions (relative, absolute, vertical), predicted positions
EKF_GPS_GLITCHING = 0x8000


def _copter_heartbeat(ph: Phase) -> Build:
    base = MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | MAV_MODE_FLAG_STABILIZE_ENABLED | MAV_MODE_FLAG_GUIDED_ENABLED
    if ph.mode == "AUTO":
        base |= MAV_MODE_FLAG_AUTO_ENABLED
    if ph.armed:
        base |= MAV_MODE_FLAG_SAFETY_ARMED
    return lambda mav: mav.heartbeat_encode(MAV_TYPE_QUADROTOR, MAV_AUTOPILOT_ARDUPILOTMEGA, base, COPTER[ph.mode],
                                            ph.status, 3)


def _spoof_offset(t: float) -> tuple[float, float]:
    return (0.0, SPOOF_JUMP_EAST_M) if t >= SPOOF_AT else (0.0, 0.0)


def gps_spoof(outdir: Path) -> dict[str, Any]:
    rng = Random(22)
    script = Script()
    veh, gcs = (VEHICLE_SYSID, VEHICLE_COMPID), (GCS_SYSID, GCS_COMPID)
    beats = _telemetry(script, 60, SPOOF_KEYS, SPOOF_PHASES, _copter_heartbeat, 5, True,
                       utc_jump=(TIME_JUMP_AT, TIME_JUMP_US), gps_offset=_spoof_offset, ekf_offset_from=EKF_RESET_AT)
    for sec in range(60):
        script.add(sec + 0.5 + rng.randint(0, 900) / 1e6, "gcs", lambda mav: gcs_heartbeat(mav, None, 0))
        t = sec + 0.3
        flags, vel_var, pos_var = HEALTHY_EKF, 0.1, 0.1
        if 20.0 <= t < 24.0:  # dead reckoning through the jamming: uncertainty grows, below the alarm level
            pos_var = 0.3 + (t - 20.0) * 0.1
        if SPOOF_AT <= t < EKF_RESET_AT:
            flags, vel_var, pos_var = HEALTHY_EKF | EKF_GPS_GLITCHING, 0.4, 1.6
        script.add(t, "vehicle", lambda mav, fl=flags, v=vel_var, p=pos_var: mav.ekf_status_report_encode(
            fl, v, p, 0.1, 0.05, 0.0), "ekf")
    commands = []
    for at, cmd, params, mode in ((5.0, MAV_CMD_COMPONENT_ARM_DISARM, (1.0,), None),
                                  (6.0, MAV_CMD_DO_SET_MODE, (1.0, float(COPTER["AUTO"])), "AUTO")):
        p = list(params) + [0.0] * (7 - len(params))
        tag = f"cmd{len(commands)}"
        script.add(at, "gcs", lambda mav, c=cmd, p=p: mav.command_long_encode(*veh, c, 0, *p), tag)
        script.add(at + 0.011, "vehicle", lambda mav, c=cmd: mav.command_ack_encode(c, MAV_RESULT_ACCEPTED, 0, 0, *gcs),
                   tag + "ack")
        commands.append({"tag": tag, "from": list(gcs), "command": cmd, "params": p[:3], "result": MAV_RESULT_ACCEPTED,
                         "mode": mode})
    for at, sev, text in ((20.1, MAV_SEVERITY_WARNING, "GPS 1: no fix"),
                          (30.4, MAV_SEVERITY_WARNING, "GPS Glitch"),
                          (32.0, MAV_SEVERITY_CRITICAL, "EKF Failsafe: changed to LAND Mode"),
                          (47.6, MAV_SEVERITY_INFO, "Disarming motors")):
        script.add(at, "vehicle", lambda mav, s=sev, x=text: mav.statustext_encode(s, x.encode()), "statustext")
    endpoints = {"vehicle": Endpoint(apm, *veh), "gcs": Endpoint(apm, *gcs)}
    sends, tags = script.pack(endpoints)
    flow = UdpFlow({"vehicle": (LOOPBACK_V4, VEHICLE_UDP_PORT), "gcs": (LOOPBACK_V4, GCS_UDP_PORT)}, rng)
    summary = _pcap(outdir, "gps_spoof.pcap", sends, {"vehicle": flow, "gcs": flow})
    arming, modes = _heartbeat_changes(tags, beats)
    for c in commands:
        c["record"], c["ack_record"] = tags[c["tag"]][0], tags[c["tag"] + "ack"][0]
    gps_times = [k / 5 + 0.05 for k in range(300)]
    gpi_times = [k / 5 + 0.02 for k in range(300)]
    st_times = [s + 0.5 for s in range(60)]
    ekf_times = [s + 0.3 for s in range(60)]

    def first(tag: str, times: list[float], cond: Callable[[float], bool]) -> int:
        return next(r for r, t in zip(tags[tag], times) if cond(t))

    gps_jump = first("gps", gps_times, lambda t: t >= SPOOF_AT)
    gpi_jump = first("gpi", gpi_times, lambda t: t >= EKF_RESET_AT)
    collapse = first("gps", gps_times, lambda t: t >= 20.0)
    ekf_alarm = first("ekf", ekf_times, lambda t: t >= SPOOF_AT)
    time_jump = first("system_time", st_times, lambda t: t >= TIME_JUMP_AT)
    truth = {
        "vehicle": list(veh), "gcs": list(gcs), "autopilot": "ArduPilot", "vehicle_type": "QUADROTOR",
        "arming": arming, "modes": modes,
        "commands": [{k: v for k, v in c.items() if k != "tag"} for c in commands],
        "statustext_records": tags["statustext"],
        "failsafe_statustext_record": tags["statustext"][2],
        "jamming": {"from_s": 20.0, "until_s": 24.0, "first_record": collapse, "satellites": [16, 3],
                    "fix_type": [GPS_FIX_TYPE_3D_FIX, GPS_FIX_TYPE_NO_FIX]},
        "spoof": {"jump_east_m": SPOOF_JUMP_EAST_M, "gps_record": gps_jump, "global_position_record": gpi_jump,
                  "speed_mps": 8.0},
        "ekf_glitch_record": ekf_alarm,
        "time_jump": {"record": time_jump, "seconds": TIME_JUMP_US / 1e6},
        "findings": {
            "gnss-fix-collapse": [[collapse]],
            "gnss-position-jump": [[gpi_jump], [gps_jump]],
            "ekf-gnss-alarm": [[ekf_alarm]],
            "gnss-time-jump": [[time_jump]],
        },
    }
    summary["truth_file"] = write_truth(outdir, "gps_spoof.pcap", truth)
    return summary
