"""Property tests: the filter parser and compiler raise nothing but FilterError, whatever the input, and
a filter that compiles evaluates to a bool on any frame."""

from __future__ import annotations

from functools import cache

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mavscope.capture.detect import open_capture
from mavscope.filter import FilterError, compile_filter
from mavscope.mavlink.dialect import Dialect, load_dialect
from mavscope.mavlink.frame import Frame
from mavscope.pipeline.dissect import Dissector
from tests.conftest import CAPTURES

DIALECT: Dialect = load_dialect()


@cache
def sample_frames() -> tuple[Frame, ...]:
    """A few frames of every kind the captures hold: clean, damaged, signed, TCP, tlog."""
    out: list[Frame] = []
    for name in ("px4_sitl_udp.pcap", "damaged.pcap", "signed_udp.pcap", "px4_sitl_tcp.pcap", "px4_sitl.tlog"):
        with open_capture(CAPTURES / name) as reader:
            frames = [f for f in Dissector(DIALECT).run(reader) if isinstance(f, Frame)]
        out.extend(frames[:: max(1, len(frames) // 40)])
    return tuple(out)

PIECES = st.sampled_from([
    "mavlink.sysid", "mavlink_proto.msgid", "HEARTBEAT", "COMMAND_LONG.command", "command", "x", "ip.src",
    "udp.port", "frame.time", "signature.status", "mavlink.crc_status", "STATUSTEXT.text", "mavlink.payload",
    "==", "!=", "<", "<=", ">", ">=", "&", "&&", "||", "!", "and", "or", "not", "contains", "matches", "in",
    "{", "}", "(", ")", ",", "1", "0x49", "-3.5", "1..5", "MAV_CMD_NAV_RETURN_TO_LAUNCH", '"a(b"', '"ok"',
    "127.0.0.1", "10.0.0.0/8", "bad", "80:74", "'", '"', "\\", "$", "1e999", "..",
])


def check(text: str) -> None:
    try:
        flt = compile_filter(text, DIALECT)
    except FilterError as exc:
        assert 0 <= exc.position <= len(text)
        assert str(exc).startswith("filter error: ")
        return
    for frame in sample_frames():
        assert flt.matches(frame) in (True, False)


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.text(max_size=60))
def test_random_text(text: str) -> None:
    check(text)


@settings(max_examples=600, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(PIECES, max_size=12))
def test_random_token_soup(pieces: list[str]) -> None:
    check(" ".join(pieces))


def test_deep_nesting_is_an_error_not_a_crash() -> None:
    check("(" * 5000 + "HEARTBEAT" + ")" * 5000)
    check("!" * 5000 + "HEARTBEAT")
