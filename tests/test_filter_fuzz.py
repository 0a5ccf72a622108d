"""Property tests: the filter parser and compiler raise nothing but FilterError, whatever the input."""

from __future__ import annotations

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mavscope.analysis.filter import FilterError, compile_filter
from mavscope.mavlink.dialect import Dialect, load_dialect

DIALECT: Dialect = load_dialect()

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
