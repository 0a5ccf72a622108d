"""Hypothesis strategies for captures that the `stats` analyses have something to say about.

Random payloads (test_generated.py) almost never make a HEARTBEAT of a vehicle, a mode request or a
position jump. These strategies draw the messages the expert detectors read with values that matter to
them: vehicles and ground stations (HEARTBEAT types, autopilots, armed or not, ArduPilot, PX4 and
MAV_MODE modes, custom modes no enum names), commands to one vehicle or to all (arming, disarming with
param1 0, DO_SET_MODE with whole, fractional, negative, huge, NaN and infinite params, commands that
are not control), SET_MODE, mission uploads of 0 items and clears of each mission type, manual control
and offboard setpoints, landed states and altitudes, positions that drift or jump (or sit at 0, 0, or
out of range), GPS fixes that collapse, satellites unknown, speeds unknown, accuracy, boot clocks that
step back (reboots) and UTC clocks that jump, EKF and estimator flags and ratios; from senders whose
sequence numbers step on, skip, repeat, come late or restart, some signing, over several UDP endpoint
pairs (channels and conversations), in pcap, tlog or raw files, with records the walker hands back
among them (bad CRCs, TCP, unsigned frames of signing senders, SETUP_SIGNING) and frames copied byte
for byte later (replays). Field values are packed with `struct` from the message's FieldDefs.
"""

from __future__ import annotations

import struct

from hypothesis import strategies as st

from mavscope.mavlink.dialect import MessageDef, load_dialect
from tests.native import build as nh
from tests.native.test_generated import frame as random_frame

DIALECT = load_dialect()
BY_NAME = {md.name: md for md in DIALECT.messages.values()}
CODES = {"uint8_t": "B", "uint8_t_mavlink_version": "B", "int8_t": "b", "uint16_t": "H", "int16_t": "h",
         "uint32_t": "I", "int32_t": "i", "uint64_t": "Q", "int64_t": "q", "float": "f", "double": "d", "char": "s"}


def pack(md: MessageDef, values: dict[str, object]) -> bytes:
    """The payload of `md` with `values` (the other fields zero), in wire order, trailing zeros trimmed."""
    out = b""
    for f in md.fields:
        code = CODES[f.type]
        v = values.get(f.name, 0)
        if f.type == "char":
            out += struct.pack(f"<{max(f.array_length, 1)}s", v if isinstance(v, bytes) else b"")
        elif f.array_length:
            out += struct.pack(f"<{f.array_length}{code}", *([v] * f.array_length))
        else:
            out += struct.pack("<" + code, v)
    return out.rstrip(b"\0") or out[:1]


VEHICLES = [(1, 1), (2, 1), (1, 2)]  # (1, 2): a second component of vehicle 1
GCS = [(255, 190), (254, 1), (0, 0)]
TARGETS = [1, 1, 2, 0, 255, 254, 7]
F32 = [0.0, -0.0, 1.0, 1.5, 3.0, 4.0, 6.0, 216.0, 209.0, 81.0, -1.0, 1e30, 65536.0, 2.0**40,
       float("nan"), float("inf"), float("-inf")]
MODES = [0, 3, 5, 6, 4 << 16 | 4 << 24, 3 << 16 | 1 << 24, 3 << 16, 6 << 16, 99, 4 << 16 | 99 << 24, 0xFFFFFFFF]
BASE_MODES = [0x81, 0x81, 0x01, 0x89, 0x01, 0xD1, 0x59, 0x80, 0x10, 0]
COMMANDS = [400, 400, 176, 176, 22, 20, 21, 511, 246, 65535]
LAT, LON = 473977418, 85455939
VEHICLE_MESSAGES = ["HEARTBEAT", "HEARTBEAT", "HEARTBEAT", "EXTENDED_SYS_STATE", "GLOBAL_POSITION_INT",
                    "GLOBAL_POSITION_INT", "GPS_RAW_INT", "GPS_RAW_INT", "GPS2_RAW", "SYSTEM_TIME",
                    "EKF_STATUS_REPORT", "ESTIMATOR_STATUS", "ATTITUDE", "MISSION_COUNT"]
GCS_MESSAGES = ["HEARTBEAT", "COMMAND_LONG", "COMMAND_LONG", "COMMAND_INT", "SET_MODE", "SET_MODE",
                "MISSION_COUNT", "MISSION_CLEAR_ALL", "MANUAL_CONTROL", "RC_CHANNELS_OVERRIDE",
                "SET_POSITION_TARGET_LOCAL_NED", "MISSION_ITEM_INT", "PARAM_SET", "SET_MODE"]


def _clock(draw: st.DrawFn, state: dict[str, int], key: str) -> int:
    """A boot clock in ms that runs on, and sometimes steps back (a reboot) or jumps."""
    now = state.get(key, draw(st.integers(0, 10**6)))
    step = draw(st.sampled_from([200, 200, 200, 500, 1000, 1000, 3000, 20_000, -5000, -now]))
    state[key] = max(0, now + step)
    return state[key]


def _position(draw: st.DrawFn, state: dict[str, int], key: str) -> dict[str, object]:
    """A sender's position: drifting, now and then jumping (or at 0, 0, or out of range)."""
    lat = state.get(key + "lat", LAT) + draw(st.sampled_from([0, 10, 50, 3000, 100_000, 10**7, -(10**6)]))
    state[key + "lat"] = lat
    return {"lat": draw(st.sampled_from([lat, lat, lat, 0, 10**9])), "lon": draw(st.sampled_from([LON, LON, 0]))}


@st.composite
def message(draw: st.DrawFn, state: dict[str, int], sender: tuple[int, int]) -> tuple[MessageDef, dict[str, object]]:
    """One analysis message of `sender` (a vehicle's telemetry, or a ground station's commands)."""
    vehicle = sender in VEHICLES
    name = draw(st.sampled_from(VEHICLE_MESSAGES if vehicle else GCS_MESSAGES))
    target = draw(st.sampled_from(TARGETS))
    v: dict[str, object] = {"target_system": target, "target": target, "target_component": 1}
    key = f"{sender}"
    if name == "HEARTBEAT":
        mav_type = state.setdefault(key + "type", draw(st.sampled_from([2, 2, 1, 12, 10, 18, 26] if vehicle
                                                                       else [6, 6, 6, 26])))
        v |= {"type": draw(st.sampled_from([mav_type] * 8 + [0, 13])),
              "autopilot": state.setdefault(key + "ap", draw(st.sampled_from([3, 3, 12, 8, 0]))),
              "base_mode": draw(st.sampled_from(BASE_MODES)), "custom_mode": draw(st.sampled_from(MODES)),
              "system_status": draw(st.sampled_from([3, 4, 5])), "mavlink_version": 3}
    elif name in ("COMMAND_LONG", "COMMAND_INT"):
        v |= {"command": draw(st.sampled_from(COMMANDS))}
        v |= {f"param{i}": draw(st.sampled_from(F32)) for i in (1, 2, 3)}
    elif name == "SET_MODE":
        v |= {"base_mode": draw(st.sampled_from(BASE_MODES)), "custom_mode": draw(st.sampled_from(MODES))}
    elif name in ("MISSION_COUNT", "MISSION_CLEAR_ALL"):
        v |= {"count": draw(st.sampled_from([0, 0, 3])), "mission_type": draw(st.sampled_from([0, 0, 1, 2, 255]))}
    elif name == "EXTENDED_SYS_STATE":
        v |= {"landed_state": draw(st.sampled_from([0, 1, 2, 2, 3, 4]))}
    elif name == "GLOBAL_POSITION_INT":
        v |= _position(draw, state, key + name)
        v |= {"time_boot_ms": _clock(draw, state, key + "boot"), "vx": draw(st.sampled_from([0, 300, -2000, 32767])),
              "vy": draw(st.sampled_from([0, 100, -32768])),
              "relative_alt": draw(st.sampled_from([0, 5000, 50_000, 50_000, -3000]))}
    elif name in ("GPS_RAW_INT", "GPS2_RAW"):
        v |= _position(draw, state, key + name)
        boot = _clock(draw, state, key + name) * 1000
        unix = 1_700_000_000_000_000 + boot + draw(st.sampled_from([0, 0, 0, 10**7, -(10**8)]))
        v |= {"time_usec": draw(st.sampled_from([boot, unix, unix])),
              "fix_type": draw(st.sampled_from([3, 3, 3, 4, 6, 0, 1, 2])),
              "vel": draw(st.sampled_from([0, 500, 65535])),
              "satellites_visible": draw(st.sampled_from([12, 12, 10, 3, 5, 0, 255])),
              "h_acc": draw(st.sampled_from([0, 800, 9_999_999, 2**31]))}
    elif name == "SYSTEM_TIME":
        boot = _clock(draw, state, key + "boot")
        v |= {"time_boot_ms": boot, "time_unix_usec": draw(st.sampled_from(
            [0, 1_700_000_000_000_000 + boot * 1000, 1_700_000_000_000_000 + boot * 1000 + 5 * 10**6]))}
    elif name in ("EKF_STATUS_REPORT", "ESTIMATOR_STATUS"):
        v |= {"flags": draw(st.sampled_from([0x1FF, 0x1FF, 0x17, 0x17, 0x0F, 0x8017, 0x417, 0x400, 0x7F, 0x413])),
              "velocity_variance": draw(st.sampled_from([0.1, 0.1, 0.5, 1.5, float("nan")])),
              "pos_horiz_variance": draw(st.sampled_from([0.2, 0.2, 2.0])),
              "vel_ratio": draw(st.sampled_from([0.1, 0.1, 1.2, float("inf")])),
              "pos_horiz_ratio": draw(st.sampled_from([0.3, 0.3, 3.0])),
              "time_usec": _clock(draw, state, key + name) * 1000 * draw(st.sampled_from([1, 1, 0]))}
    return BY_NAME[name], v


@st.composite
def story_frame(draw: st.DrawFn, state: dict[str, int]) -> bytes:
    """A frame of one of the senders: an analysis message (or now and then anything), its sequence number
    stepping on, skipping, repeating, coming late or restarting; signed or not; now and then damaged."""
    sysid, compid = sender = draw(st.sampled_from(VEHICLES + GCS))
    key = f"seq{sysid}.{compid}"
    seq = state.get(key, draw(st.integers(0, 255)))
    seq = (seq + draw(st.sampled_from([1] * 12 + [2, 3, 0, -1, -2, 15, 60, 129, 200]))) % 256
    if draw(st.integers(0, 40)) == 0:
        seq = 0
    state[key] = seq
    if draw(st.integers(0, 12)) == 0:
        return draw(random_frame())
    md, values = draw(message(state, sender))
    signing = sysid in (2, 254) and draw(st.integers(0, 5)) > 0
    f = nh.frame_v2(md, md.id, pack(md, values), seq, sysid, compid, iflags=1 if signing else 0,
                    timestamp=(1_700_000_000 - nh.SIGNING_EPOCH) * 100_000 + seq)
    if draw(st.integers(0, 25)) == 0:  # a bad CRC: handed back, BadCrcBursts
        at = len(f) - (13 if signing else 0) - 2
        f = f[:at] + bytes([f[at] ^ 1]) + f[at + 1 :]
    return f


def _next_seq(state: dict[str, int], sender: tuple[int, int], step: int = 1) -> int:
    key = f"seq{sender[0]}.{sender[1]}"
    state[key] = (state.get(key, 0) + step) % 256
    return state[key]


def _frame(state: dict[str, int], sender: tuple[int, int], name: str, values: dict[str, object],
           step: int = 1, bad_crc: bool = False) -> bytes:
    md = BY_NAME[name]
    f = nh.frame_v2(md, md.id, pack(md, values), _next_seq(state, sender, step), *sender)
    return f[:-1] + bytes([f[-1] ^ 1]) if bad_crc else f


V, A, B = (1, 1), (255, 190), (254, 1)  # a vehicle, two ground stations
HB_GCS = {"type": 6, "autopilot": 8, "base_mode": 0, "mavlink_version": 3}


@st.composite
def episode(draw: st.DrawFn, state: dict[str, int]) -> list[bytes]:
    """A few frames that make one finding (or nearly: a value is now and then off)."""
    what = draw(st.sampled_from(["jump", "collapse", "mode", "disarm", "utc", "gps_utc", "ekf", "reorder",
                                 "interleave", "bad_crc", "intrusion"]))
    ap = draw(st.sampled_from([3, 3, 12]))
    mode = draw(st.sampled_from([0, 5, 6, 4 << 16 | 4 << 24, 3 << 16]))
    other = draw(st.sampled_from([3, 5, 9, 4 << 16 | 3 << 24, 3 << 16 | 1 << 24]))
    hb = {"type": draw(st.sampled_from([2, 2, 1, 12])), "autopilot": ap, "system_status": 4, "mavlink_version": 3}
    boot = _clock(draw, state, f"{V}boot")
    step = draw(st.sampled_from([200, 200, 1000, 4000, 12_000]))
    unix = 1_700_000_000_000_000
    pos = {"lat": LAT, "lon": LON}
    if what == "jump":
        far = {"lat": LAT + draw(st.sampled_from([100_000, 10**6, 300])), "lon": LON}
        name = draw(st.sampled_from(["GLOBAL_POSITION_INT", "GPS_RAW_INT"]))
        clock = "time_boot_ms" if name == "GLOBAL_POSITION_INT" else "time_usec"
        scale = 1 if clock == "time_boot_ms" else 1000
        fix = {"fix_type": 3, "satellites_visible": 12, "vel": draw(st.sampled_from([100, 65535])), "vx": 100}
        state[f"{V}boot"] = boot + step
        return [_frame(state, V, name, pos | fix | {clock: boot * scale}),
                _frame(state, V, name, far | fix | {clock: (boot + step) * scale})]
    if what == "collapse":
        return [_frame(state, V, "GPS_RAW_INT", pos | {"time_usec": boot * 1000, "fix_type": 3,
                                                       "satellites_visible": draw(st.sampled_from([12, 255]))}),
                _frame(state, V, "GPS_RAW_INT", pos | {"time_usec": (boot + step) * 1000,
                                                       "fix_type": draw(st.sampled_from([1, 2, 3, 0])),
                                                       "satellites_visible": draw(st.sampled_from([3, 12, 255]))})]
    if what in ("mode", "intrusion", "disarm"):
        out = [_frame(state, A, "HEARTBEAT", HB_GCS), _frame(state, B, "HEARTBEAT", HB_GCS),
               _frame(state, V, "HEARTBEAT", hb | {"base_mode": 0x81, "custom_mode": mode}),
               _frame(state, A, "COMMAND_LONG", {"target_system": 1, "command": 400, "param1": 1.0})]
        if what == "mode":
            if draw(st.booleans()):
                out.append(_frame(state, B, "SET_MODE", {"target_system": 1, "base_mode": 1, "custom_mode": other}))
            else:
                out.append(_frame(state, B, "COMMAND_LONG", {"target_system": 1, "command": 176, "param1": 1.0,
                                                             "param2": float(other >> 16 if ap == 12 else other),
                                                             "param3": float(other >> 24)}))
            return [*out, _frame(state, V, "HEARTBEAT", hb | {"base_mode": 0x81, "custom_mode": other})]
        if what == "intrusion":
            name = draw(st.sampled_from(["RC_CHANNELS_OVERRIDE", "MANUAL_CONTROL", "COMMAND_LONG",
                                         "MISSION_CLEAR_ALL", "MISSION_COUNT"]))
            return [*out, _frame(state, B, name, {"target_system": 1, "target": 1, "command": 22, "count": 0})]
        alt = draw(st.sampled_from(["landed", "alt", "none"]))
        if alt == "landed":
            out.append(_frame(state, V, "EXTENDED_SYS_STATE", {"landed_state": draw(st.sampled_from([2, 3, 1]))}))
        elif alt == "alt":
            out.append(_frame(state, V, "GLOBAL_POSITION_INT", {"time_boot_ms": boot, "relative_alt": 50_000}))
        if draw(st.booleans()):
            out.append(_frame(state, B, "COMMAND_LONG", {"target_system": 1, "command": 400, "param1": 0.0}))
        return [*out, _frame(state, V, "HEARTBEAT", hb | {"base_mode": 0x01, "custom_mode": mode})]
    if what == "utc":
        jump = draw(st.sampled_from([5 * 10**6, -(3 * 10**6), 10**5]))
        return [_frame(state, V, "SYSTEM_TIME", {"time_boot_ms": boot, "time_unix_usec": unix + boot * 1000}),
                _frame(state, V, "SYSTEM_TIME", {"time_boot_ms": boot + step,
                                                 "time_unix_usec": unix + (boot + step) * 1000 + jump})]
    if what == "gps_utc":
        off = draw(st.sampled_from([10**7, -(6 * 10**6), 10**5]))
        return [_frame(state, V, "SYSTEM_TIME", {"time_boot_ms": boot, "time_unix_usec": unix + boot * 1000}),
                _frame(state, V, "GLOBAL_POSITION_INT", {"time_boot_ms": boot + step}),
                _frame(state, V, "GPS_RAW_INT", pos | {"time_usec": unix + (boot + step) * 1000 + off, "fix_type": 3})]
    if what == "ekf":
        name = draw(st.sampled_from(["EKF_STATUS_REPORT", "ESTIMATOR_STATUS"]))
        bad = draw(st.sampled_from([0x8017, 0x0F, 0x417, 0x413, 0x17]))
        ratio = {"velocity_variance": draw(st.sampled_from([0.1, 1.5])), "vel_ratio": draw(st.sampled_from([0.1, 2.0]))}
        return [_frame(state, V, name, {"flags": 0x17, "time_usec": boot * 1000}),
                _frame(state, V, name, {"flags": bad, "time_usec": (boot + step) * 1000} | ratio)]
    if what == "reorder":
        return [_frame(state, V, "ATTITUDE", {}, 1), _frame(state, V, "ATTITUDE", {}, 3),
                _frame(state, V, "ATTITUDE", {}, -1), _frame(state, V, "ATTITUDE", {}, 2)]
    if what == "interleave":
        out = []
        for i in range(draw(st.integers(6, 14))):
            out.append(_frame(state, V, "ATTITUDE", {}, 100 if i % 2 else -99))
        return out
    return [_frame(state, (3, 1), "ATTITUDE", {}, bad_crc=True) for _ in range(draw(st.integers(2, 4)))]


ENDPOINTS = [(bytes([10, 0, 0, 1]), 14550), (bytes([10, 0, 0, 2]), 14555), (bytes([10, 0, 0, 1]), 14551),
             (bytes([192, 168, 1, 7]), 14550)]


@st.composite
def story(draw: st.DrawFn) -> bytes:
    """A capture of story frames: pcap (UDP between a few endpoints, sometimes TCP), tlog or raw; times
    that run on with now and then a gap of hours or years (the rate bins' width doubles)."""
    state: dict[str, int] = {}
    frames: list[bytes] = []
    for _ in range(draw(st.integers(1, 40))):
        if draw(st.integers(0, 3)) == 0:
            frames += draw(episode(state))
        else:
            frames.append(draw(story_frame(state)))
    if draw(st.booleans()) and len(frames) > 3:  # copies of earlier frames later on (replays, duplicates)
        for _ in range(draw(st.integers(1, 4))):
            i = draw(st.integers(0, len(frames) - 1))
            frames.insert(draw(st.integers(i, len(frames))), frames[i])
    t = 1_700_000_000.0
    times = []
    for _ in frames:
        t += draw(st.sampled_from([0.0, 0.001, 0.02, 0.1, 0.1, 0.2, 0.2, 0.2, 0.5, 1.0, 2.5, 3600.0, 86400.0 * 400]))
        times.append(t)
    container = draw(st.sampled_from(["pcap", "pcap", "pcap", "tlog", "tlog", "raw"]))
    if container == "tlog":
        return nh.tlog([(int(ts * 1e6), f) for ts, f in zip(times, frames)])
    if container == "raw":
        return b"".join(frames)
    records = []
    for ts, f in zip(times, frames):
        (src, sport), (dst, dport) = draw(st.sampled_from(ENDPOINTS)), draw(st.sampled_from(ENDPOINTS))
        if draw(st.integers(0, 12)) == 0:
            l4, proto = nh.tcp(sport, dport, draw(st.integers(0, 2**32 - 1)), f), 6
        else:
            l4, proto = nh.udp(sport, dport, f), 17
        records.append((int(ts), int(ts % 1 * 1e6), nh.link("ethernet", nh.ipv4(src, dst, proto, l4), False)))
    return nh.pcap(records, nh.LINKTYPES["ethernet"])
