"""The TUI's column filter (mavscope.browse.fastfilter) against the compiled display filter, row for row.

The reference is `DisplayFilter.matches` on every frame rebuilt from the index (what the TUI's filter
worker ran before): the column filter must select exactly those rows, for the filters of
tests/filter/test_filter.py and more (every registered header, transport, verdict, note and signature
field, payload fields, time and number comparisons, and/or/not), on every bundled capture (with and
without a signing key), the real captures, and Hypothesis-drawn combinations of tests.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mavscope.browse.fastfilter import ColumnFilter
from mavscope.browse.index import FrameIndex
from mavscope.capture.detect import open_capture
from mavscope.filter import FilterError, compile_filter
from mavscope.mavlink.dialect import load_dialect
from mavscope.pipeline.dissect import Dissector
from mavscope.security.stage import SecurityStage
from tests.conftest import CAPTURES
from tests.native.engines import material

DIALECT = load_dialect()
ALL = sorted(p for p in CAPTURES.iterdir() if p.suffix in (".pcap", ".pcapng", ".tlog", ".raw"))

TESTS = [  # single tests: each alone, negated, and joined at random below
    "mavlink.msgid == 73", "mavlink.msgid eq 0x49", "mavlink.msgid == MISSION_ITEM_INT", "mavlink.sysid == 255",
    "mavlink.sysid != 255", "mavlink.sysid == 1", "mavlink.seq < 10", "mavlink.seq >= 250", "mavlink.compid == 1",
    "mavlink.msgid in {0 30 33}", "mavlink.msgid in {0, 30..33}", "mavlink.msgname == HEARTBEAT",
    "mavlink.msgname matches \"^ATT\"", "mavlink.msgname", "frame.number <= 100", "frame.number in {3, 7..9}",
    "frame.number > 2.5", "frame.number & 1", "frame.index == 2", "frame.len > 40", "frame.time > 0",
    "frame.time < 1700000000.5", "frame.time", "frame.time in {0..1600000000}", "frame.transport == tlog",
    "frame.transport == udp", "frame.src contains \"14580\"", "frame.dst", "HEARTBEAT", "ATTITUDE", "COMMAND_LONG",
    "HEARTBEAT.type == MAV_TYPE_QUADROTOR", "type == MAV_TYPE_GCS", "COMMAND_LONG.command == 20",
    "command == MAV_CMD_NAV_RETURN_TO_LAUNCH", "COMMAND_ACK.result == MAV_RESULT_ACCEPTED", "ATTITUDE.roll > 0",
    "ATTITUDE.roll != 0", "STATUSTEXT.text contains \"a\"", "STATUSTEXT.text matches \"[Pp]re\"", "roll",
    "mavlink.crc_status == bad", "mavlink.crc_status == ok", "crc_status == unchecked", "mavlink.crc > 1000",
    "mavlink.len == 9", "mavlink.version == 1", "mavlink.signed", "mavlink.incompat_flags == 1",
    "signature.status == valid", "signature.status == no-key", "signature.status == invalid", "signature.status",
    "signature.key", "signature.link_id == 0", "signature.timestamp > 0", "signature", "encryption",
    "encryption.status", "note.skipped-bytes", "note.unknown-msgid", "ip.src == 127.0.0.1", "ip.addr == 10.0.0.0/8",
    "ip.dst != 127.0.0.1", "udp.port == 14550", "udp.srcport == 14580", "tcp.port == 5760", "udp.dstport > 14000",
    "mavlink.sysid == mavlink.compid", "mavlink.seq > mavlink.sysid", "mavlink.payload contains 00:00",
    "HEARTBEAT.custom_mode > mavlink.sysid", "HEARTBEAT.custom_mode & 4", "HEARTBEAT.mavlink_version == 3",
    "SYSTEM_TIME.time_unix_usec > 1600000000000000", "SYSTEM_TIME.time_unix_usec", "ATTITUDE.yaw in {-1..1, 3}",
    "GLOBAL_POSITION_INT.relative_alt > 10000", "seq > 3", "lat != 0", "time_boot_ms > 1000", "ATTITUDE.roll == 0.0",
    "SYS_STATUS.onboard_control_sensors_present & 0x20", "target_system == 1", "COMMAND_LONG.param1 > 0.5",
    "roll < -0.01", "type in {1, 2, 6}", "GPS_RAW_INT.alt_ellipsoid >= 0", "HEARTBEAT.type != 6",
]
FILTERS = TESTS + [f"!({t})" for t in TESTS] + [
    "mavlink.sysid == 1 && HEARTBEAT", "not HEARTBEAT and not ATTITUDE", "HEARTBEAT || ATTITUDE",
    "(HEARTBEAT or ATTITUDE) && mavlink.sysid == 1", "ATTITUDE.roll > 0 || mavlink.sysid == 255",
    "mavlink.crc_status == bad || note.skipped-bytes", "!(signature.status == valid) && mavlink.signed",
]


@cache
def index_of(name: str, keys: str = "none") -> FrameIndex:
    path = CAPTURES / name if not name.startswith("/") else Path(name)
    index = FrameIndex(DIALECT, path)
    with open_capture(path) as reader:
        index.build(SecurityStage(material(keys)).run(Dissector(DIALECT).run(reader)))
    return index


def check(index: FrameIndex, text: str) -> int:
    """The column filter's rows equal the compiled filter's on every frame; the matches."""
    try:
        flt = compile_filter(text, DIALECT)
    except FilterError:
        return -1
    expected = [n for n in index.rows() if flt.matches(index.frame(n))]
    fast = ColumnFilter(flt, index)
    got = fast.matches(index.first, index.end).tolist()
    assert got == expected, text
    split = [r for _, hits in fast.scan(index.first, index.end) for r in hits.tolist()]  # blocks
    assert split == expected, text
    return len(expected)


@pytest.mark.parametrize("path", ALL, ids=lambda p: p.name)
def test_every_filter_on_every_capture(path: Path) -> None:
    index = index_of(path.name)
    matched = [check(index, text) for text in FILTERS]
    assert any(m > 0 for m in matched) and any(m == 0 for m in matched)


@pytest.mark.parametrize("name", ["signed_udp.pcap", "securemav_udp.pcap", "key_exchange_udp.pcap",
                                  "gcs_takeover.pcap"])
@pytest.mark.parametrize("keys", ["key", "leaked"])
def test_verdicts_with_keys(name: str, keys: str) -> None:
    index = index_of(name, keys)
    for text in FILTERS:
        check(index, text)


def test_grouped_tests_rebuild_a_frame_per_distinct_value() -> None:
    """`mavlink.sysid == 1` over 1371 frames rebuilds one frame per sysid, not one per row."""
    index = index_of("px4_sitl_udp.pcap")
    fast = ColumnFilter(compile_filter("mavlink.sysid == 1 && !HEARTBEAT", DIALECT), index)
    assert len(fast.matches(0, len(index))) > 0
    assert fast.frames_tested <= len({index.row(n).sysid for n in index.rows()}) + \
        len({index.row(n).msgid for n in index.rows()})
    payload = ColumnFilter(compile_filter("HEARTBEAT.type == 2", DIALECT), index)
    assert len(payload.matches(0, len(index))) > 0
    assert payload.frames_tested == 0  # decoded with numpy from the file's bytes
    text = ColumnFilter(compile_filter('STATUSTEXT.text contains "a"', DIALECT), index)
    text.matches(0, len(index))
    assert text.frames_tested == sum(index.row(n).msgname == "STATUSTEXT" for n in index.rows()) > 0  # those only


def test_real_captures(real_captures: Path) -> None:
    for path in sorted(real_captures.iterdir()):
        if path.suffix in (".pcap", ".pcapng", ".tlog", ".raw", ".bin"):
            index = index_of(str(path))
            for text in ("HEARTBEAT", "mavlink.sysid == 1", "signature.status == no-key", "mavlink.crc_status == bad",
                         "ATTITUDE.roll > 0", "frame.time > 0 && !GLOBAL_POSITION_INT", "note.skipped-bytes"):
                check(index, text)


def test_a_bounded_index_after_drops() -> None:
    """Row numbers keep meaning across drops: the column filter gives the held rows' numbers."""
    full = index_of("px4_sitl_udp.pcap")
    index = FrameIndex(DIALECT, CAPTURES / "px4_sitl_udp.pcap")
    index.limit = 400
    for n in full.rows():
        index.add(full.frame(n))
    assert index.first > 0
    for text in ("HEARTBEAT", "mavlink.sysid == 1", "ATTITUDE.roll > 0", "frame.number > 900"):
        check(index, text)


@settings(max_examples=150, deadline=None, suppress_health_check=list(HealthCheck), derandomize=True)
@given(st.sampled_from([p.name for p in ALL]),
       st.recursive(st.sampled_from(TESTS),
                    lambda inner: st.one_of(st.tuples(inner, st.sampled_from([" && ", " || "]), inner).map(
                        lambda t: f"({t[0]}{t[1]}{t[2]})"), inner.map(lambda t: f"!{t}")), max_leaves=5))
def test_generated_filters(name: str, text: str) -> None:
    check(index_of(name), text)


@settings(max_examples=100, deadline=None, suppress_health_check=list(HealthCheck), derandomize=True)
@given(st.sampled_from(["mavlink.sysid", "mavlink.seq", "mavlink.msgid", "frame.number", "frame.time",
                        "frame.len", "udp.port", "HEARTBEAT.type", "ATTITUDE.roll", "mavlink.crc",
                        "SYSTEM_TIME.time_unix_usec", "HEARTBEAT.custom_mode", "GLOBAL_POSITION_INT.lat", "seq",
                        "ATTITUDE.yawspeed", "type", "SCALED_PRESSURE.temperature"]),
       st.sampled_from(["==", "!=", "<", "<=", ">", ">=", "&"]),
       st.one_of(st.integers(-3, 300), st.integers(-2**64, 2**64), st.floats(allow_nan=False, allow_infinity=False,
                                                                             width=32).map(lambda x: round(x, 3))))
def test_generated_comparisons(name: str, op: str, number: float) -> None:
    check(index_of("px4_sitl_udp.pcap"), f"{name} {op} {number}")
    check(index_of("mavlink_v1_udp.pcap"), f"{name} {op} {number}")


@pytest.mark.parametrize("path", ALL, ids=lambda p: p.name)
def test_without_dense_tables(path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Keys over more values than a dense lookup table takes are answered per distinct value."""
    from mavscope.browse import fastfilter

    monkeypatch.setattr(fastfilter, "DENSE", 4)
    index = index_of(path.name)
    for text in ("mavlink.sysid == 1", "HEARTBEAT || ATTITUDE", "signature.status == no-key", "udp.port == 14550",
                 "!(mavlink.msgid in {0..30})", "frame.src contains \"145\""):
        check(index, text)


from tests.native.test_generated import capture  # noqa: E402


@settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck), derandomize=True)
@given(capture(), st.sampled_from(["none", "key"]), st.lists(st.sampled_from(TESTS), min_size=1, max_size=3))
def test_generated_captures(data: bytes, keys: str, tests: list[str]) -> None:
    """Captures of random frames (unknown and large message ids, damaged, signed, encrypted, TCP, tlog):
    each test alone and all of them joined."""
    from tests.native.engines import capture_file

    with capture_file(data) as path:
        try:
            index = FrameIndex(DIALECT, path)
            with open_capture(path) as reader:
                index.build(SecurityStage(material(keys)).run(Dissector(DIALECT).run(reader)))
        except Exception:  # noqa: BLE001 - a file no reader opens: nothing to filter
            return
        for text in [*tests, " || ".join(f"({t})" for t in tests), " && ".join(f"!({t})" for t in tests)]:
            check(index, text)
        index.close()
