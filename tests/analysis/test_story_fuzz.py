"""Property test: the event sources and the control and GNSS detectors never raise and keep their state
bounded, whatever the payloads of the messages they read (random bytes with valid CRCs, built by the
generator's independent encoder, scripts/capgen/encode.py, with pymavlink's CRC_EXTRA)."""

from __future__ import annotations

import struct
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import all as pm

from mavscope.analysis.events import EventLog
from mavscope.analysis.expert import Expert
from mavscope.capture.detect import open_capture
from mavscope.mavlink.dialect import Dialect
from mavscope.pipeline.dissect import Anomaly, Dissector
from scripts.capgen.encode import encode_frame

READ = ["HEARTBEAT", "SYSTEM_TIME", "MISSION_CURRENT", "MISSION_ITEM_REACHED", "STATUSTEXT", "COMMAND_LONG",
        "COMMAND_INT", "COMMAND_ACK", "SET_MODE", "PARAM_SET", "PARAM_VALUE", "FILE_TRANSFER_PROTOCOL",
        "SETUP_SIGNING", "GLOBAL_POSITION_INT", "GPS_RAW_INT", "GPS2_RAW", "EKF_STATUS_REPORT", "ESTIMATOR_STATUS",
        "EXTENDED_SYS_STATE", "RC_CHANNELS_OVERRIDE", "MANUAL_CONTROL", "MISSION_CLEAR_ALL", "MISSION_COUNT",
        "SET_ATTITUDE_TARGET", "PARAM_EXT_SET", "PARAM_EXT_VALUE", "PARAM_EXT_ACK", "AUTOPILOT_VERSION", "LOG_ENTRY",
        "LOG_REQUEST_DATA", "LOG_DATA", "LOG_REQUEST_END", "DATA_TRANSMISSION_HANDSHAKE", "ENCAPSULATED_DATA"]
MESSAGES = [(getattr(pm, f"MAVLINK_MSG_ID_{n}"), pm.mavlink_map[getattr(pm, f"MAVLINK_MSG_ID_{n}")]) for n in READ]

frame_st = st.tuples(st.integers(0, len(MESSAGES) - 1), st.integers(1, 4), st.integers(1, 3),
                     st.binary(min_size=0, max_size=255), st.floats(0, 30, allow_nan=False))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(frame_st, min_size=1, max_size=120))
def test_random_payloads(tmp_path: Path, dialect: Dialect, frames: list) -> None:  # type: ignore[type-arg]
    out, t = bytearray(), 1_773_482_400.0
    for i, (which, sysid, compid, payload, dt) in enumerate(frames):
        msgid, cls = MESSAGES[which]
        body = (payload + bytes(255))[: cls.unpacker.size]
        t += dt
        out += struct.pack(">Q", round(t * 1e6)) + encode_frame(msgid, body, cls.crc_extra, seq=i % 256,
                                                                 sysid=sysid, compid=compid)
    path = tmp_path / "fuzz.tlog"
    path.write_bytes(bytes(out))
    log, expert = EventLog(dialect), Expert(dialect)
    with open_capture(str(path)) as r:
        for f in Dissector(dialect).run(r):
            if type(f) is not Anomaly:
                log.add(f)
                expert.add(f)
    result = log.finish()
    expert.findings()
    assert len(result.events) <= sum(result.counts.values())
    assert all(e.frame >= 1 for e in result.events)
