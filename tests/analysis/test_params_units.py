"""The pieces of the parameter analysis: the param.pck decoder against pymavlink's (MAVProxy's) decoder on
files the generator's independent encoder packs; the two integer encodings of PARAM_VALUE, confirmations,
retries and the answer window on flows pymavlink builds; parameter files; security categories."""

from __future__ import annotations

import struct
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as v2
from pymavlink.mavftp import MAVFTP

from mavscope.analysis.params import (
    ParamFileError,
    analyse,
    category,
    decode,
    disables,
    read_param_text,
    same,
    value_text,
)
from mavscope.mavlink.dialect import Dialect
from scripts.capgen.parampck import pack
from tests.support.builders import heartbeat_msg
from tests.support.ftpflows import Flow, frames_of

names = st.text("ABCDEFGHIJKLMNOPQRSTUVWXYZ_0123456789", min_size=1, max_size=16)
values = st.one_of(st.tuples(st.just(1), st.integers(-128, 127)), st.tuples(st.just(2), st.integers(-32768, 32767)),
                   st.tuples(st.just(3), st.integers(-2**31, 2**31 - 1)),
                   st.tuples(st.just(4), st.floats(width=32, allow_nan=False)))


@settings(max_examples=150, deadline=None)
@given(st.dictionaries(names, values, min_size=1, max_size=60), st.sampled_from([80, 110, 239]))
def test_pck_decodes_as_pymavlink_does(table: dict[str, tuple[int, float]], read_size: int) -> None:
    data = pack([(n, t, v) for n, (t, v) in table.items()], read_size)
    ref = MAVFTP.ftp_param_decode(data)
    got = decode(data)
    assert ref is not None and got.problems == ()
    assert [(p.name, p.ap_type) for p in got.params] == [(n.decode(), t) for n, _v, t in ref.params]
    for p, (_n, v, t) in zip(got.params, ref.params, strict=True):
        assert (struct.pack("<f", p.value) == struct.pack("<f", v)) if t == 4 else p.value == v


def test_pck_problems_never_raise() -> None:
    good = pack([("ABC", 3, 7), ("ABD", 4, 1.5)], 239)
    assert decode(good[:5]).problems == ("5 bytes: shorter than the 6-byte header",)
    assert decode(b"\x00\x00" + good[2:]).problems[0].startswith("magic 0x0000")
    cut = decode(good[:-2])
    assert [p.name for p in cut.params] == ["ABC"] and "cut short" in cut.problems[0]
    bad_type = decode(good[:6] + bytes([9, 0x20]) + b"XYZ")
    assert "unknown parameter type 9" in bad_type.problems[0]
    bad_prefix = decode(good[:6] + bytes([1, 0x05]) + b"X" + b"\x01")
    assert "shared with a previous name" in bad_prefix.problems[0]


def pv(name: str, value: float, ptype: int, count: int = 3) -> object:
    return v2.MAVLink_param_value_message(name.encode(), value, ptype, count, 0)


def ps(name: str, value: float, ptype: int, target: tuple[int, int] = (1, 1)) -> object:
    return v2.MAVLink_param_set_message(target[0], target[1], name.encode(), value, ptype)


def hb(autopilot: int) -> object:
    return heartbeat_msg(2, autopilot, 0)


def int_as_float(v: int) -> float:
    """An INT32 sent byte-wise (PX4): its bytes in the float field."""
    return struct.unpack("<f", struct.pack("<i", v))[0]


def test_integer_encodings(tmp_path: Path, dialect: Dialect) -> None:
    flow = Flow()
    flow.send((1, 1), hb(12))  # PX4: byte-wise
    flow.send((1, 1), pv("SYS_AUTOSTART", int_as_float(4001), 6))
    flow.send((1, 1), pv("MPC_XY_VEL_MAX", 12.0, 9))
    log = analyse(frames_of(flow.write(tmp_path), dialect))
    assert log.final == {"MPC_XY_VEL_MAX": 12.0, "SYS_AUTOSTART": 4001}
    flow = Flow()
    flow.send((1, 1), hb(3))  # ArduPilot: C cast
    flow.send((1, 1), pv("SYSID_THISMAV", 1.0, 6))
    log = analyse(frames_of(flow.write(tmp_path), dialect))
    assert log.final == {"SYSID_THISMAV": 1} and log.components[0].encoding_basis == "HEARTBEAT"
    flow = Flow()  # no HEARTBEAT: a non-integral float of an integer type can only be byte-wise
    flow.send((1, 1), pv("CBRK_IO_SAFETY", int_as_float(22027), 6))
    log = analyse(frames_of(flow.write(tmp_path), dialect))
    assert log.final == {"CBRK_IO_SAFETY": 22027} and log.components[0].encoding == "bytewise"


def test_confirmation_retries_and_the_answer_window(tmp_path: Path, dialect: Dialect) -> None:
    flow = Flow()
    flow.send((1, 1), hb(3))
    flow.send((1, 1), pv("FENCE_ENABLE", 1.0, 2))
    flow.send((1, 1), pv("RTL_ALT", 1500.0, 6))
    flow.send((255, 190), ps("FENCE_ENABLE", 0.0, 2))
    flow.send((255, 190), ps("FENCE_ENABLE", 0.0, 2), dt=1.0)  # a retry
    flow.send((1, 1), pv("FENCE_ENABLE", 0.0, 2))  # confirmed
    flow.send((255, 190), ps("RTL_ALT", 99999.0, 6))
    flow.send((1, 1), pv("RTL_ALT", 8000.0, 6))  # clamped: answered with another value
    flow.send((255, 190), ps("RTL_ALT", 2000.0, 6, target=(1, 0)))
    flow.send((1, 1), pv("RTL_ALT", 2000.0, 6), dt=6.0)  # after the window: no answer, a change
    log = analyse(frames_of(flow.write(tmp_path), dialect))
    got = [(e.kind, e.name, e.value, e.previous, e.confirmed, e.retries, e.reported) for e in log.timeline]
    assert got == [("set", "FENCE_ENABLE", 0, 1, True, 1, 0), ("set", "RTL_ALT", 99999, 1500, False, 0, 8000),
                   ("set", "RTL_ALT", 2000, 8000, None, 0, None), ("change", "RTL_ALT", 2000, 8000, None, 0, None)]
    assert log.final == {"FENCE_ENABLE": 0, "RTL_ALT": 2000}
    assert [f.code for f in log.findings] == ["param-protection-disabled"]


def test_param_ext_ack(tmp_path: Path, dialect: Dialect) -> None:
    flow = Flow()
    cam = (1, 100)
    flow.send(cam, v2.MAVLink_param_ext_value_message(b"CAM_ISO", struct.pack("<I", 100), 5, 1, 0))
    flow.send((255, 190), v2.MAVLink_param_ext_set_message(1, 100, b"CAM_ISO", struct.pack("<I", 6400), 5))
    flow.send(cam, v2.MAVLink_param_ext_ack_message(b"CAM_ISO", struct.pack("<I", 100), 5, 3))  # in progress
    flow.send(cam, v2.MAVLink_param_ext_ack_message(b"CAM_ISO", struct.pack("<I", 100), 5, 2))  # failed
    log = analyse(frames_of(flow.write(tmp_path), dialect))
    [e] = log.timeline
    assert (e.source, e.value, e.previous, e.confirmed, e.ack) == ("PARAM_EXT_SET", 6400, 100, False,
                                                                   "PARAM_ACK_FAILED")
    assert log.final == {"CAM_ISO": 100} and log.main == cam


def test_value_text_round_trips_float32() -> None:
    for v in (0.3, 1e-7, 123456.79, -0.0, 3.4e38, 1 / 3):
        f = struct.unpack("<f", struct.pack("<f", v))[0]
        text = value_text(f)
        assert struct.pack("<f", float(text)) == struct.pack("<f", f)
        assert len(text) <= 20 and "e" not in text or abs(f) >= 1e15
    assert value_text(0.3) == "0.3" and value_text(5) == "5" and value_text(float("nan")) == "nan"
    assert same(1, 1.0) and same(0.3, 0.30000001192092896) and not same(0.3, 0.31)


def test_parameter_files() -> None:
    assert read_param_text("A 1\nB,2.5 # note\n# comment\n") == {None: {"A": 1, "B": 2.5}}
    assert read_param_text("# Vehicle-Id Component-Id Name Value Type\n1\t1\tX\t0x10\t6\n") == {(1, 1): {"X": 16}}
    for bad in ("", "A\n", "A b\n", "A B C\n", "1\t1\tX\tY\t9\n", "A-B 1\n"):
        with pytest.raises(ParamFileError):
            read_param_text(bad)


def test_security_categories() -> None:
    assert category("SYSID_ENFORCE") == "signing and access" and category("MAV3_OPTIONS") == "signing and access"
    assert category("FS_GCS_ENABLE") == "failsafe" and category("NAV_DLL_ACT") == "failsafe"
    assert category("GF_ACTION") == "fence" and category("CBRK_SUPPLY_CHK") == "arming checks"
    assert category("SCR_ENABLE") == "scripting" and category("WPNAV_SPEED") is None
    assert disables("ARMING_CHECK", 0) == "every pre-arm check" and disables("ARMING_CHECK", 1) is None
    assert disables("MAV2_OPTIONS", 5) is not None and disables("MAV2_OPTIONS", 4) is None
