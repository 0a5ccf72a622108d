"""`mavscope params` on real captures, against decoders and readers that are not mavscope's.

- The plane tlog's three @PARAM/param.pck reads, exported by `mavscope objects --out`, decoded by
  pymavlink's `mavftp.MAVFTP.ftp_param_decode` (MAVProxy's decoder, moved into pymavlink) and by MAVProxy's
  own (`MAVProxy.modules.lib.param_ftp`, MAVProxy 1.8.75, which `make test` installs). MAVProxy's decoder
  prints `paramftp: bad count 1435 should be 1425` and gives None for the first read (its header says
  1425 and it holds 1435); MAVPROXY below holds the digests (`digest`) it gives for the other two, written
  out for reading and compared with both decoders at test time.
- The rover's 55 PARAM_SETs and the PX4 and ArduSub PARAM_VALUE/PARAM_EXT_VALUE, read by pymavlink record by
  record (tests/support/pymavlink_reader.py): rover 55 sets, 55 confirmed; PX4 739 names; ArduSub 887
  names and 14 PARAM_EXT_VALUE.
"""

from __future__ import annotations

import hashlib
import struct
from pathlib import Path

import pytest
from pymavlink.mavftp import MAVFTP

from tests.conftest import Cli
from tests.support.pymavlink_reader import read

PLANE = "ap_plane_sitl_mission3types_ftp_mp_mavproxy.tlog"
ROVER = "ap_rover_mission_fence_rally_params.tlog"
PX4 = "px4_2018_params_offboard.tlog"
SUB = "ardusub_log_tools_small.tlog"
MAVPROXY = [None, "6e34e9cca4284a4df4b87bdff1b7c28934db9747c753a9cc12faa826d6661fba",
            "000acf3ff7ddf758ded85f7423617da2751e62dceb26602026baee380d54fc3f"]
INT_FORMATS = {1: "<B", 2: "<b", 3: "<H", 4: "<h", 5: "<I", 6: "<i"}


def capture(real_captures: Path, name: str) -> Path:
    path = real_captures / name
    if not path.is_file():
        pytest.skip(f"{path} is absent")
    return path


def f32(v: float) -> bytes:
    return struct.pack("<f", v)


def digest(params: list) -> str:
    lines = sorted(f"{n.decode()}={f32(v).hex() if t == 4 else int(v)}:{t}" for n, v, t in params)
    return hashlib.sha256("\n".join(lines).encode()).hexdigest()


def test_plane_param_pck_decodes_as_mavproxy_does(cli: Cli, real_captures: Path, tmp_path: Path) -> None:
    path = capture(real_captures, PLANE)
    objects = cli.json("objects", path, "--out", tmp_path)["objects"]
    doc = cli.json("params", path)
    assert [x["sha256"] for x in doc["ftp"]] == [o["sha256"] for o in objects]
    for n, (obj, ftp) in enumerate(zip(objects, doc["ftp"], strict=True)):
        decoded = MAVFTP.ftp_param_decode((tmp_path / obj["file"]).read_bytes())
        if MAVPROXY[n] is None:  # refused by MAVProxy and pymavlink: the header's count is not the file's
            assert decoded is None
            assert ftp["problems"] == ["the header says 1425 parameters, the file holds 1435"]
            assert ftp["decoded"] == 1435
            continue
        assert decoded is not None and digest(decoded.params) == MAVPROXY[n]
        assert ftp["decoded"] == len(decoded.params) == 1435 and ftp["problems"] == []
        values = ftp["values"]
        assert sorted(values) == sorted(name.decode() for name, _v, _t in decoded.params)
        for name, value, ptype in decoded.params:
            got = values[name.decode()]
            assert (f32(got) == f32(value)) if ptype == 4 else got == value
    # the final values last reported by Mission Planner's read are that file's
    last = MAVFTP.ftp_param_decode((tmp_path / objects[-1]["file"]).read_bytes())
    main = next(c for c in doc["components"] if [c["sysid"], c["compid"]] == [1, 1])
    from_file = {n for n, p in main["parameters"].items() if p["source"] == "FTP @PARAM/param.pck"}
    assert len(from_file) > 1400
    for name, value, ptype in last.params:
        if name.decode() in from_file:
            got = doc["final"][name.decode()]
            assert (f32(got) == f32(value)) if ptype == 4 else got == value
    assert doc["main_component"] == [1, 1] and len(doc["final"]) == 1435


def test_rover_sets_confirmed(cli: Cli, real_captures: Path) -> None:
    path = capture(real_captures, ROVER)
    msgs = read(path)
    want = []
    for i, m in enumerate(msgs):
        if m.name != "PARAM_SET":
            continue
        name = m.msg.param_id
        reply = next((r for r in msgs[i + 1:] if r.name == "PARAM_VALUE" and r.src[0] == m.msg.target_system
                      and r.msg.param_id == name), None)
        want.append((name, f32(m.msg.param_value), reply is not None and f32(reply.msg.param_value) ==
                     f32(m.msg.param_value)))
    doc = cli.json("params", path)
    sets = [e for e in doc["timeline"] if e["kind"] == "set"]
    assert [(e["name"], f32(e["value"]), e["confirmed"]) for e in sets] == want
    assert len(sets) == doc["confirmed"] == 55
    assert all(e["from"] == [250, 250] and e["signature"] == "unsigned" for e in sets)


def test_px4_values_are_bytewise(cli: Cli, real_captures: Path) -> None:
    path = capture(real_captures, PX4)
    last: dict[str, tuple[bytes, int]] = {}
    for m in read(path):
        if m.name == "PARAM_VALUE" and m.src == (1, 1):
            # the float field's 4 bytes (pymavlink unpacks a float32 into a double: packing it back is exact)
            last[m.msg.param_id] = (f32(m.msg.param_value), m.msg.param_type)
    doc = cli.json("params", path)
    main = next(c for c in doc["components"] if [c["sysid"], c["compid"]] == [1, 1])
    assert (main["encoding"], main["encoding_basis"]) == ("bytewise", "HEARTBEAT")  # PX4's HEARTBEAT
    assert sorted(doc["final"]) == sorted(last) and len(last) == 739
    for name, (raw, ptype) in last.items():
        fmt = INT_FORMATS.get(ptype)
        if fmt is None:
            assert f32(doc["final"][name]) == raw
        else:
            assert doc["final"][name] == struct.unpack(fmt, raw[: struct.calcsize(fmt)])[0], name


def test_ardusub_param_ext(cli: Cli, real_captures: Path) -> None:
    path = capture(real_captures, SUB)
    names: dict[tuple[int, int], set[str]] = {}
    for m in read(path):
        if m.name in ("PARAM_VALUE", "PARAM_EXT_VALUE"):
            names.setdefault(m.src, set()).add(m.msg.param_id)
    doc = cli.json("params", path)
    got = {(c["sysid"], c["compid"]): set(c["parameters"]) for c in doc["components"]}
    assert got == names
    assert len(names[(1, 1)]) == 887 and len(names[(1, 100)]) == 14


def test_mavproxys_own_decoder_agrees(cli: Cli, real_captures: Path, tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    param_ftp = pytest.importorskip("MAVProxy.modules.lib.param_ftp",
                                    reason="MAVProxy is not installed (make test installs it)")
    path = capture(real_captures, PLANE)
    objects = cli.json("objects", path, "--out", tmp_path)["objects"]
    capsys.readouterr()
    got = []
    for obj in objects:
        decoded = param_ftp.ftp_param_decode((tmp_path / obj["file"]).read_bytes())
        got.append(None if decoded is None else (len(decoded.params), digest(decoded.params)))
    assert got == [None, (1435, MAVPROXY[1]), (1435, MAVPROXY[2])]
    assert "paramftp: bad count 1435 should be 1425" in capsys.readouterr().out
