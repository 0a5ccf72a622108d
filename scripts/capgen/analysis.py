"""Captures with a known analysis truth (docs/analysis.md): link loss and duplicates, mission
transfers, commands and their ACKs, clock offset and drift. Each scripts its messages exactly, so that
the truth in expected.json is what was put in, not what an analysis found."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from random import Random
from typing import Any

import pymavlink.dialects.v20.common as mav2

from .constants import (
    BASE_TIME_US,
    GCS_COMPID,
    GCS_SYSID,
    GCS_UDP_PORT,
    LINKTYPE_ETHERNET,
    LOOPBACK_V4,
    MAV_AUTOPILOT_PX4,
    MAV_CMD_COMPONENT_ARM_DISARM,
    MAV_CMD_DO_REPOSITION,
    MAV_CMD_NAV_RETURN_TO_LAUNCH,
    MAV_CMD_NAV_TAKEOFF,
    MAV_CMD_NAV_WAYPOINT,
    MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    MAV_MISSION_ACCEPTED,
    MAV_MISSION_TYPE_MISSION,
    MAV_RESULT_ACCEPTED,
    NAN,
    VEHICLE_COMPID,
    VEHICLE_LINK_ID,
    VEHICLE_SYSID,
    VEHICLE_UDP_PORT,
)
from .frames import Endpoint, Frame, Send
from .packets import UdpFlow
from .story import SHORT_STORY, Keyframe, Story, to_degE7, vehicle_state
from .summary import summarize_packets
from .telemetry import Profile, build_session, gcs_heartbeat, vehicle_heartbeat
from .writers import write_pcap

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
    """Add one HEARTBEAT a second per side, so that the scripted captures look like live links."""
    quad = vehicle_heartbeat(MAV_AUTOPILOT_PX4)
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
    """A MISSION_ITEM_INT builder (NaN yaw for waypoints, as QGC sends; item 0 current)."""
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
