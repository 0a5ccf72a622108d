"""Captures of objects moved over the link, with their truth: an FTP parameter download with parameter
changes (ftp_params.pcap), a Lua script upload with retried and lost packets (ftp_lua_upload.pcap), a log
download (log_download.pcap). Each truth file (`<capture>.truth.json`) is written from what the generator
sent: the files' bytes, which packets it left out, which sets the vehicle took."""

from __future__ import annotations

import hashlib
import json
import struct
import zlib
from pathlib import Path
from random import Random
from typing import Any

import pymavlink.dialects.v20.common as mav2

from .constants import (
    GCS_LINK_ID,
    MAV_AUTOPILOT_ARDUPILOTMEGA,
    MAV_AUTOPILOT_INVALID,
    MAV_TYPE_GCS,
    MAV_TYPE_QUADROTOR,
)
from .frames import Endpoint
from .ftpsim import ACK, EOF, Entry, Script, udp_flows, write_capture
from .ftpsim import FtpClient as Ftp
from .parampck import MAV_PARAM_TYPES, float32, pack, pack_upload

VEHICLE, GCS, CAMERA, ROGUE = (1, 1), (255, 190), (1, 100), (66, 190)
OP_OPEN_RO, OP_READ, OP_TERMINATE, OP_BURST = 4, 5, 1, 15
READ_SIZE = 239
BURST_PACKETS = 4
MAV_TYPE_CAMERA = 30
MAV_PARAM_EXT_TYPE_UINT8, MAV_PARAM_EXT_TYPE_REAL32 = 1, 9
PARAM_ACK_ACCEPTED, PARAM_ACK_IN_PROGRESS = 0, 3


def parameter_table() -> list[tuple[str, int, float]]:
    """An ArduCopter-like parameter set (name, AP type 1 int8 / 2 int16 / 3 int32 / 4 float, value)."""
    table: list[tuple[str, int, float]] = [
        ("FORMAT_VERSION", 2, 120), ("SYSID_THISMAV", 2, 1), ("SYSID_MYGCS", 2, 255), ("SYSID_ENFORCE", 1, 0),
        ("MAV1_OPTIONS", 2, 0), ("ACRO_YAW_P", 4, 4.5), ("AHRS_EKF_TYPE", 1, 3), ("AHRS_GPS_GAIN", 4, 1.0),
        ("ARMING_CHECK", 3, 1), ("ARMING_REQUIRE", 1, 1), ("BATT_CAPACITY", 3, 3300), ("BATT_FS_CRT_ACT", 1, 1),
        ("BATT_FS_LOW_ACT", 1, 2), ("BATT_MONITOR", 1, 4), ("COMPASS_OFS_X", 4, -12.5), ("COMPASS_OFS_Y", 4, 33.25),
        ("FENCE_ACTION", 1, 1), ("FENCE_ALT_MAX", 4, 120.0), ("FENCE_ENABLE", 1, 1), ("FENCE_RADIUS", 4, 300.0),
        ("FENCE_TYPE", 1, 7), ("FS_GCS_ENABLE", 1, 1), ("FS_THR_ENABLE", 1, 1), ("FS_THR_VALUE", 2, 975),
        ("GPS_TYPE", 1, 1), ("LOG_BITMASK", 3, 176126), ("RTL_ALT", 3, 1500), ("SCR_ENABLE", 1, 0),
        ("SCR_HEAP_SIZE", 3, 43008), ("STAT_RUNTIME", 3, 123456), ("WPNAV_ACCEL", 4, 250.0),
        ("WPNAV_SPEED", 4, 500.0), ("WPNAV_SPEED_DN", 4, 150.0), ("WPNAV_SPEED_UP", 4, 250.0),
    ]
    for n in range(1, 17):
        table += [(f"RC{n}_MIN", 2, 1100), (f"RC{n}_MAX", 2, 1900), (f"RC{n}_TRIM", 2, 1500 + n)]
    for n in range(1, 17):
        table += [(f"SERVO{n}_FUNCTION", 2, 33 + n if n <= 4 else 0), (f"SERVO{n}_MIN", 2, 1000),
                  (f"SERVO{n}_MAX", 2, 2000), (f"SERVO{n}_REVERSED", 1, 0), (f"SERVO{n}_TRIM", 2, 1500)]
    return table


def _value(ptype: int, v: float) -> float | int:
    return float32(v) if ptype == 4 else int(v)


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def heartbeat(side_type: int, autopilot: int) -> Any:
    return lambda mav: mav.heartbeat_encode(side_type, autopilot, 0, 0, 3)


def heartbeats(script: Script, seconds: int, sides: dict[str, tuple[int, int]]) -> None:
    """One HEARTBEAT a second per side (MAV_TYPE, MAV_AUTOPILOT), as a live link has."""
    for sec in range(seconds):
        for i, (side, (kind, autopilot)) in enumerate(sides.items()):
            script.entries.append(Entry(sec * 1_000_000 + 500 + i * 137, side, heartbeat(kind, autopilot)))


def param_value(name: str, ptype: int, value: float, count: int, index: int) -> Any:
    return lambda mav: mav.param_value_encode(name.encode(), float(value), MAV_PARAM_TYPES[ptype], count, index)


def param_set(target: tuple[int, int], name: str, ptype: int, value: float) -> Any:
    return lambda mav: mav.param_set_encode(target[0], target[1], name.encode(), float(value), MAV_PARAM_TYPES[ptype])


def ftp_download(ftp: Ftp, path: str, data: bytes, session: int, *, lose: set[int] = frozenset(),
                 refetch: bool = True) -> dict[str, Any]:
    """OpenFileRO, burst reads of READ_SIZE bytes (BURST_PACKETS a burst, the EOF NAK in the last one), the
    packets numbered in `lose` left out of the capture and, with `refetch`, read again with ReadFile;
    TerminateSession. Returns the truth of the object."""
    open_req = ftp.request(OP_OPEN_RO, data=path.encode())
    announced = len(data) // READ_SIZE * READ_SIZE + 2 * READ_SIZE  # an over-estimate, as ArduPilot's
    ftp.reply(open_req, session=session, data=announced.to_bytes(4, "little"))
    offset, packet, missing = 0, 0, []
    while True:
        burst = ftp.request(OP_BURST, session=session, size=READ_SIZE, offset=offset)
        for i in range(BURST_PACKETS):
            if offset >= len(data):
                ftp.nak(burst, EOF, offset=len(data), seq=burst.seq + 1 + i)
                break
            chunk = data[offset : offset + READ_SIZE]
            last = i == BURST_PACKETS - 1
            ftp.reply(burst, data=chunk, offset=offset, seq=burst.seq + 1 + i, burst_complete=int(last),
                      lost=packet in lose, gap_us=2_000)
            if packet in lose:
                missing.append((offset, offset + len(chunk)))
            offset += len(chunk)
            packet += 1
        else:
            continue
        break
    gaps = []
    for start, stop in missing:
        if refetch:
            req = ftp.request(OP_READ, session=session, size=READ_SIZE, offset=start)
            ftp.reply(req, data=data[start:stop])
        else:
            gaps.append([start, stop])
    term = ftp.request(OP_TERMINATE, session=session)
    ftp.reply(term)
    return {"kind": "ftp-read", "path": path, "direction": "download", "sender": list(VEHICLE),
            "receiver": list(ftp.me), "session": session, "size": len(data), "sha256": sha256(data),
            "complete": not gaps, "gaps": gaps, "lost_packets": len(missing)}


def ftp_params(outdir: Path) -> dict[str, Any]:
    """A parameter download over FTP (param.pck), then parameter sets from the signed GCS and an unsigned
    second system, a PARAM_EXT_SET to a camera, a value the vehicle changes itself, and a second param.pck
    read with a lost burst packet read again."""
    rng = Random(21)
    script = Script(rng)
    heartbeats(script, 24, {"vehicle": (MAV_TYPE_QUADROTOR, MAV_AUTOPILOT_ARDUPILOTMEGA),
                            "gcs": (MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID),
                            "camera": (MAV_TYPE_CAMERA, MAV_AUTOPILOT_INVALID)})
    table = parameter_table()
    values = {n: (t, _value(t, v)) for n, t, v in table}
    ftp = Ftp(script, "gcs", GCS, VEHICLE)
    script.at(1_200_000)
    first = pack([(n, t, v) for n, t, v in table], READ_SIZE)
    objects = [ftp_download(ftp, "@PARAM/param.pck", first, 0)]
    timeline: list[dict[str, Any]] = []
    count = len(table)
    index = {n: i for i, (n, _t, _v) in enumerate(table)}

    def setp(side: str, who: tuple[int, int], name: str, value: float, *, answer: float | None, tries: int = 1,
             security: str | None = None, disables: str | None = None) -> None:
        t, old = values[name]
        for k in range(tries):
            script.send(side, param_set(VEHICLE, name, t, value), 1_500_000 if k else 400_000)
        if answer is not None:
            script.send("vehicle", param_value(name, t, answer, count, index[name]), 6_000)
            values[name] = (t, _value(t, answer))
        timeline.append({"kind": "set", "name": name, "value": _value(t, value), "previous": old, "from": list(who),
                         "component": list(VEHICLE), "confirmed": None if answer is None else
                         _value(t, answer) == _value(t, value), "reported": None if answer is None else
                         _value(t, answer), "retries": tries - 1, "signed": side == "gcs", "security": security,
                         "disables": disables})

    script.at(6_000_000)
    setp("gcs", GCS, "SCR_ENABLE", 1, answer=1, security="scripting")
    setp("gcs", GCS, "WPNAV_SPEED", 5000.0, answer=2000.0)  # the vehicle clamps it to its maximum
    setp("gcs", GCS, "FENCE_ENABLE", 0, answer=None, tries=3, security="fence", disables="the geofence")
    script.at(11_000_000)
    setp("rogue", ROGUE, "ARMING_CHECK", 0, answer=0, security="arming checks", disables="every pre-arm check")
    setp("rogue", ROGUE, "MAV1_OPTIONS", 1, answer=1, security="signing and access",
         disables="signature checking: the link accepts unsigned MAVLink 2 frames")
    script.at(13_000_000)
    t, old = values["STAT_RUNTIME"]
    script.send("vehicle", param_value("STAT_RUNTIME", t, 123516, count, index["STAT_RUNTIME"]))
    values["STAT_RUNTIME"] = (t, 123516)
    timeline.append({"kind": "change", "name": "STAT_RUNTIME", "value": 123516, "previous": old,
                     "from": list(VEHICLE), "component": list(VEHICLE), "confirmed": None, "reported": None,
                     "retries": 0, "signed": False, "security": None, "disables": None})
    # the camera's parameters (PARAM_EXT), and one set with an IN_PROGRESS then ACCEPTED answer
    script.at(14_000_000)
    script.send("camera", lambda mav: mav.param_ext_value_encode(b"CAM_MODE", bytes([1]), MAV_PARAM_EXT_TYPE_UINT8,
                                                                 2, 0))
    script.send("camera", lambda mav: mav.param_ext_value_encode(b"CAM_EV", float32_bytes(0.5),
                                                                 MAV_PARAM_EXT_TYPE_REAL32, 2, 1))
    script.send("gcs", lambda mav: mav.param_ext_set_encode(*CAMERA, b"CAM_MODE", bytes([2]), MAV_PARAM_EXT_TYPE_UINT8),
                200_000)
    script.send("camera", lambda mav: mav.param_ext_ack_encode(b"CAM_MODE", bytes([1]), MAV_PARAM_EXT_TYPE_UINT8,
                                                               PARAM_ACK_IN_PROGRESS))
    script.send("camera", lambda mav: mav.param_ext_ack_encode(b"CAM_MODE", bytes([2]), MAV_PARAM_EXT_TYPE_UINT8,
                                                               PARAM_ACK_ACCEPTED), 300_000)
    timeline.append({"kind": "set", "name": "CAM_MODE", "value": 2, "previous": 1, "from": list(GCS),
                     "component": list(CAMERA), "confirmed": True, "reported": 2, "retries": 0, "signed": True,
                     "security": None, "disables": None, "ack": "PARAM_ACK_ACCEPTED"})
    # the parameters read again: the vehicle's file now holds the values it took
    script.at(16_000_000)
    second = pack([(n, values[n][0], values[n][1]) for n, _t, _v in table], READ_SIZE)
    objects.append(ftp_download(ftp, "@PARAM/param.pck", second, 1, lose={5}))

    endpoints = {"vehicle": Endpoint(mav2, *VEHICLE), "camera": Endpoint(mav2, *CAMERA),
                 "gcs": Endpoint(mav2, *GCS, link_id=GCS_LINK_ID), "rogue": Endpoint(mav2, *ROGUE)}
    main = udp_flows(rng, 14_550)
    rogue = udp_flows(rng, 14_551)
    summary, _ = write_capture(outdir / "ftp_params.pcap", script, endpoints,
                               {"vehicle": (main, "vehicle"), "camera": (main, "vehicle"), "gcs": (main, "gcs"),
                                "rogue": (rogue, "gcs")})
    truth = {"objects": objects, "operations": [],
             "params": {"main_component": list(VEHICLE), "count": count,
                        "initial": {n: _value(t, v) for n, t, v in table},
                        "final": {n: v for n, (t, v) in sorted(values.items())},
                        "types": {n: MAV_PARAM_TYPES[t] for n, t, _v in table},
                        "camera_final": {"CAM_EV": 0.5, "CAM_MODE": 2}, "timeline": timeline}}
    summary["truth"] = write_truth(outdir, "ftp_params.pcap", truth)
    return summary


def float32_bytes(v: float) -> bytes:
    return struct.pack("<f", v)


def write_truth(outdir: Path, name: str, truth: dict[str, Any]) -> str:
    """`<capture>.truth.json`, one object per line where that keeps it readable; returns its name."""
    truth_name = name.rsplit(".", 1)[0] + ".truth.json"
    (outdir / truth_name).write_text(json.dumps(truth, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    return truth_name


__all__ = ["ACK", "ftp_params", "pack_upload", "parameter_table", "write_truth"]


OP_LIST, OP_CREATE, OP_WRITE, OP_REMOVE, OP_CRC32 = 3, 6, 7, 8, 14
FILE_NOT_FOUND = 10
LUA_SCRIPT = b"""-- fence_helper.lua: keeps the vehicle company
local count = 0
function update()
  count = count + 1
  if count % 50 == 0 then
    gcs:send_text(6, "helper alive " .. tostring(count))
  end
  if arming:is_armed() and param:get("FENCE_ENABLE") == 1 then
    param:set("FENCE_ENABLE", 0)
  end
  if vehicle:get_mode() == 6 then
    vehicle:set_mode(4)
  end
  return update, 200
end
""" * 3 + b"-- " + b"=" * 60 + b"\nreturn update()\n"
WRITE_SIZE = 200


def listing(ftp: Ftp, path: str, entries: list[bytes]) -> dict[str, Any]:
    """ListDirectory from entry 0 (one ACK with every entry), then the EOF NAK at the next index."""
    req = ftp.request(OP_LIST, data=path.encode())
    ftp.reply(req, data=b"".join(e + b"\0" for e in entries))
    again = ftp.request(OP_LIST, data=path.encode(), offset=len(entries))
    ftp.nak(again, EOF)
    return {"kind": "ftp-list", "path": path, "direction": "download", "sender": list(VEHICLE),
            "receiver": list(ftp.me), "entries": [{"type": "file" if e[:1] == b"F" else "directory",
                                                   "name": e[1:].split(b"\t")[0].decode(),
                                                   "size": int(e.split(b"\t")[1]) if b"\t" in e else None}
                                                  for e in entries], "complete": True}


def upload(ftp: Ftp, path: str, data: bytes, session: int, *, ack_lost: set[int] = frozenset()) -> dict[str, Any]:
    """CreateFile, WriteFile of WRITE_SIZE-byte blocks (a block whose ACK is lost is sent again with the same
    sequence number, as pymavlink retries), TerminateSession."""
    create = ftp.request(OP_CREATE, data=path.encode())
    ftp.reply(create, session=session)
    for n, offset in enumerate(range(0, len(data), WRITE_SIZE)):
        write = ftp.request(OP_WRITE, session=session, offset=offset, data=data[offset : offset + WRITE_SIZE])
        if n in ack_lost:
            ftp.reply(write, offset=offset, lost=True)
            ftp.again(write)
        ftp.reply(write, offset=offset)
    term = ftp.request(OP_TERMINATE, session=session)
    ftp.reply(term)
    return {"kind": "ftp-write", "path": path, "direction": "upload", "sender": list(ftp.me),
            "receiver": list(VEHICLE), "session": session, "size": len(data), "sha256": sha256(data),
            "complete": True, "gaps": [], "rewritten_blocks": len(ack_lost)}


def burst_read_retried(ftp: Ftp, path: str, data: bytes, session: int) -> dict[str, Any]:
    """A read whose first burst is lost whole (the client sends the same BurstReadFile again), one packet of
    the burst that follows lost too and read again with ReadFile. `data` is longer than one burst."""
    assert len(data) > BURST_PACKETS * READ_SIZE
    req = ftp.request(OP_OPEN_RO, data=path.encode())
    ftp.reply(req, session=session, data=len(data).to_bytes(4, "little"))
    burst = ftp.request(OP_BURST, session=session, size=READ_SIZE, offset=0)
    for i in range(BURST_PACKETS):  # every packet of the first burst is lost
        ftp.reply(burst, data=data[i * READ_SIZE : (i + 1) * READ_SIZE], offset=i * READ_SIZE, seq=burst.seq + 1 + i,
                  burst_complete=int(i == BURST_PACKETS - 1), lost=True, gap_us=2_000)
    ftp.again(burst)
    for i in range(BURST_PACKETS):  # packet 2 of the retried burst is lost as well
        ftp.reply(burst, data=data[i * READ_SIZE : (i + 1) * READ_SIZE], offset=i * READ_SIZE, seq=burst.seq + 1 + i,
                  burst_complete=int(i == BURST_PACKETS - 1), lost=i == 2, gap_us=2_000)
    offset = BURST_PACKETS * READ_SIZE
    nxt = ftp.request(OP_BURST, session=session, size=READ_SIZE, offset=offset)
    k = 0
    while offset < len(data):
        ftp.reply(nxt, data=data[offset : offset + READ_SIZE], offset=offset, seq=nxt.seq + 1 + k, gap_us=2_000)
        offset += READ_SIZE
        k += 1
    ftp.nak(nxt, EOF, offset=len(data), seq=nxt.seq + 1 + k)
    fill = ftp.request(OP_READ, session=session, size=READ_SIZE, offset=2 * READ_SIZE)
    ftp.reply(fill, data=data[2 * READ_SIZE : 3 * READ_SIZE])
    term = ftp.request(OP_TERMINATE, session=session)
    ftp.reply(term)
    return {"kind": "ftp-read", "path": path, "direction": "download", "sender": list(VEHICLE),
            "receiver": list(ftp.me), "session": session, "size": len(data), "sha256": sha256(data),
            "complete": True, "gaps": [], "retried_bursts": 1, "lost_packets": BURST_PACKETS + 1}


def hello_script() -> bytes:
    line = b'gcs:send_text(6, "hello from the vehicle")\n'
    return (b"-- hello.lua\nfunction update()\n" + line * 13 + b"  return update, 1000\nend\nreturn update()\n")[:610]


def ftp_lua_upload(outdir: Path) -> dict[str, Any]:
    """A Lua script written to /APM/scripts over FTP (a WriteFile retried after its ACK was lost), read back
    (a burst lost whole and retried, a packet read again), another script read with a packet lost for good,
    a log removed through a '..' path, a refused read of /etc/shadow, and parameters set by writing a
    param.pck (ArduPilot's FTP parameter upload)."""
    rng = Random(22)
    script = Script(rng)
    heartbeats(script, 20, {"vehicle": (MAV_TYPE_QUADROTOR, MAV_AUTOPILOT_ARDUPILOTMEGA),
                            "gcs": (MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID)})
    gcs = (255, 230)
    ftp = Ftp(script, "gcs", gcs, VEHICLE)
    hello = hello_script()
    script.at(1_300_000)
    objects = [listing(ftp, "/APM/scripts", [b"Fhello.lua\t%d" % len(hello), b"Dmodules"])]
    script.at(2_000_000)
    objects.append(upload(ftp, "/APM/scripts/fence_helper.lua", LUA_SCRIPT, 0, ack_lost={2}))
    script.at(5_000_000)
    crc = ftp.request(OP_CRC32, data=b"/APM/scripts/fence_helper.lua")
    ftp.reply(crc, data=(zlib_crc32(LUA_SCRIPT)).to_bytes(4, "little"))
    script.at(6_000_000)
    objects.append(burst_read_retried(ftp, "/APM/scripts/fence_helper.lua", LUA_SCRIPT, 1))
    script.at(9_000_000)
    objects.append(ftp_download_lossy(ftp, "/APM/scripts/hello.lua", hello, 2))
    script.at(11_000_000)
    rm = ftp.request(OP_REMOVE, data=b"/APM/scripts/../LOGS/00000042.BIN")
    ftp.reply(rm)
    shadow = ftp.request(OP_OPEN_RO, data=b"../../../../etc/shadow")
    ftp.nak(shadow, FILE_NOT_FOUND)
    script.at(12_000_000)
    objects.append(listing(ftp, "/APM/scripts", [b"Ffence_helper.lua\t%d" % len(LUA_SCRIPT),
                                                 b"Fhello.lua\t%d" % len(hello), b"Dmodules"]))
    script.at(14_000_000)
    sets = [("SCR_ENABLE", 1, 1), ("ARMING_CHECK", 3, 0)]
    objects.append(upload(ftp, "@PARAM/param.pck", pack_upload(sets), 3))
    endpoints = {"vehicle": Endpoint(mav2, *VEHICLE), "gcs": Endpoint(mav2, *gcs)}
    flow = udp_flows(rng, 14_550)
    summary, _ = write_capture(outdir / "ftp_lua_upload.pcap", script, endpoints,
                               {"vehicle": (flow, "vehicle"), "gcs": (flow, "gcs")})
    truth = {"objects": objects,
             "operations": [{"opcode": "CalcFileCRC32", "path": "/APM/scripts/fence_helper.lua", "result": "ACK",
                             "crc32": zlib_crc32(LUA_SCRIPT)},
                            {"opcode": "RemoveFile", "path": "/APM/scripts/../LOGS/00000042.BIN", "result": "ACK"},
                            {"opcode": "OpenFileRO", "path": "../../../../etc/shadow", "result": "NAK FileNotFound"}],
             "unsafe_paths": ["/APM/scripts/../LOGS/00000042.BIN", "../../../../etc/shadow"],
             "script_uploads": ["/APM/scripts/fence_helper.lua"],
             "params": {"timeline": [
                 {"kind": "set", "name": n, "value": int(v), "from": list(gcs), "component": list(VEHICLE),
                  "source": "FTP upload @PARAM/param.pck", "confirmed": None, "signed": False} for n, _t, v in sets]}}
    summary["truth"] = write_truth(outdir, "ftp_lua_upload.pcap", truth)
    return summary


def ftp_download_lossy(ftp: Ftp, path: str, data: bytes, session: int) -> dict[str, Any]:
    """A read whose second packet is lost and never read again (the client gives up): the gap stays."""
    truth = ftp_download(ftp, path, data, session, lose={1}, refetch=False)
    truth["sha256"] = sha256(data[:READ_SIZE] + bytes(READ_SIZE) + data[2 * READ_SIZE :])
    return truth


def zlib_crc32(data: bytes) -> int:
    return zlib.crc32(data)


LOG_DATA_LEN = 90


def log_bytes(rng: Random, size: int) -> bytes:
    """A log's bytes: DataFlash-like records (0xA3 0x95 header, a type, a random body)."""
    out = bytearray()
    while len(out) < size:
        out += bytes([0xA3, 0x95, rng.randint(128, 200)]) + bytes(rng.getrandbits(8) for _ in range(rng.randint(8, 40)))
    return bytes(out[:size])


def log_download(outdir: Path) -> dict[str, Any]:
    """LOG_REQUEST_LIST, two LOG_ENTRY; log 2 downloaded with three LOG_DATA lost and asked for again; log 1
    cancelled with LOG_REQUEST_END after 12 packets."""
    rng = Random(23)
    script = Script(rng)
    heartbeats(script, 12, {"vehicle": (MAV_TYPE_QUADROTOR, MAV_AUTOPILOT_ARDUPILOTMEGA),
                            "gcs": (MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID)})
    logs = {1: log_bytes(rng, 2000), 2: log_bytes(rng, 8950)}
    script.at(1_100_000)
    script.send("gcs", lambda mav: mav.log_request_list_encode(*VEHICLE, 0, 0xFFFF))
    for log_id, data in logs.items():
        script.send("vehicle", lambda mav, i=log_id, n=len(data): mav.log_entry_encode(i, 2, 2, 1_773_000_000 + i, n))

    def data_packet(log_id: int, ofs: int, lost: bool = False) -> None:
        chunk = logs[log_id][ofs : ofs + LOG_DATA_LEN]
        script.send("vehicle", lambda mav, c=chunk, o=ofs: mav.log_data_encode(log_id, o, len(c), c.ljust(90, b"\0")),
                    1_500, lost)

    script.at(2_000_000)
    script.send("gcs", lambda mav: mav.log_request_data_encode(*VEHICLE, 2, 0, 0xFFFF_FFFF))
    lost = {10, 11, 57}
    for n, ofs in enumerate(range(0, len(logs[2]), LOG_DATA_LEN)):
        data_packet(2, ofs, n in lost)
    for first, count in ((10 * LOG_DATA_LEN, 2 * LOG_DATA_LEN), (57 * LOG_DATA_LEN, LOG_DATA_LEN)):
        script.send("gcs", lambda mav, f=first, c=count: mav.log_request_data_encode(*VEHICLE, 2, f, c), 200_000)
        for ofs in range(first, first + count, LOG_DATA_LEN):
            data_packet(2, ofs)
    script.at(6_000_000)
    script.send("gcs", lambda mav: mav.log_request_data_encode(*VEHICLE, 1, 0, 0xFFFF_FFFF))
    for n in range(12):
        data_packet(1, n * LOG_DATA_LEN)
    script.send("gcs", lambda mav: mav.log_request_end_encode(*VEHICLE), 10_000)
    got = 12 * LOG_DATA_LEN
    endpoints = {"vehicle": Endpoint(mav2, *VEHICLE), "gcs": Endpoint(mav2, *GCS)}
    flow = udp_flows(rng, 14_550)
    summary, _ = write_capture(outdir / "log_download.pcap", script, endpoints,
                               {"vehicle": (flow, "vehicle"), "gcs": (flow, "gcs")})
    truth = {"objects": [
        {"kind": "log", "log_id": 2, "direction": "download", "sender": list(VEHICLE), "receiver": list(GCS),
         "size": len(logs[2]), "sha256": sha256(logs[2]), "complete": True, "gaps": [], "lost_packets": len(lost)},
        {"kind": "log", "log_id": 1, "direction": "download", "sender": list(VEHICLE), "receiver": list(GCS),
         "size": len(logs[1]), "sha256": sha256(logs[1][:got] + bytes(len(logs[1]) - got)), "complete": False,
         "gaps": [[got, len(logs[1])]]}]}
    summary["truth"] = write_truth(outdir, "log_download.pcap", truth)
    return summary
