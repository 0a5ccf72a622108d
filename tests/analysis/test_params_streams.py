"""Stream-rate parameters changed by REQUEST_DATA_STREAM: explained, not "with no set to explain it".

The rule comes from ArduPilot's source, read apart from mavscope: `GCS_MAVLINK::handle_request_data_stream`
(libraries/GCS_MAVLink/GCS_Param.cpp) stores 0 for start_stop 0, req_message_rate for start_stop 1 and
ignores other values; it sets the stream-rate member of the channel's group (GCS_MAVLink_Parameters.cpp:
RAW_SENS 1, EXT_STAT 2, RC_CHAN 3, RAW_CTRL 4, POSITION 6, EXTRA1 10, EXTRA2 11, EXTRA3 12 in MAV_DATA_STREAM
numbers); MAV_DATA_STREAM_ALL (0) sets every stream but PARAMS. The group is SRn_ (Parameters.cpp of the
vehicles, n the channel from 0) or MAVn_ (GCS.cpp, n from 1). The table below is written from that source.

Synthetic flows are built by pymavlink (tests/support/ftpflows.py); the plane tlog's expectations are
derived from the tlog read by pymavlink record by record (tests/support/pymavlink_reader.py) and from the
FTP reads as tests/support/real_truth.py derives them from pymavlink's messages.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as v2

from mavscope.analysis.events.records import param_event
from mavscope.analysis.params import analyse
from mavscope.mavlink.dialect import Dialect
from tests.conftest import Cli
from tests.support import real_truth
from tests.support.ftpflows import Flow, frames_of
from tests.support.pymavlink_reader import read

# MAV_DATA_STREAM -> stream-rate suffix, from GCS_Param.cpp's switch and GCS_MAVLink_Parameters.cpp's names
AP_STREAMS = {1: "RAW_SENS", 2: "EXT_STAT", 3: "RC_CHAN", 4: "RAW_CTRL", 6: "POSITION", 10: "EXTRA1", 11: "EXTRA2",
              12: "EXTRA3"}
PLANE = "ap_plane_sitl_mission3types_ftp_mp_mavproxy.tlog"


def pv(name: str, value: float, ptype: int = 4) -> object:  # MAV_PARAM_TYPE_INT16 is 4
    return v2.MAVLink_param_value_message(name.encode(), value, ptype, 10, 0)


def rds(stream: int, rate: int, start: int = 1, target: tuple[int, int] = (1, 1)) -> object:
    return v2.MAVLink_request_data_stream_message(target[0], target[1], stream, rate, start)


def test_stream_rate_changes_name_the_request(tmp_path: Path, dialect: Dialect) -> None:
    flow = Flow()
    flow.send((1, 1), v2.MAVLink_heartbeat_message(1, 3, 0, 0, 4, 3))  # ArduPilot: C cast
    for name in ("SR0_RAW_SENS", "SR1_EXTRA1", "MAV2_POSITION", "SR0_PARAMS", "SR0_RC_CHAN", "FENCE_ENABLE"):
        flow.send((1, 1), pv(name, 1.0))
    r1 = flow.send((255, 190), rds(1, 2))  # RAW_SENS at 2
    c1 = flow.send((1, 1), pv("SR0_RAW_SENS", 2.0))  # explained by r1
    r2 = flow.send((255, 230), rds(0, 4, target=(0, 0)))  # ALL at 4, broadcast: every stream but PARAMS
    c2 = flow.send((1, 1), pv("SR1_EXTRA1", 4.0))  # explained by r2 (any channel's group)
    c3 = flow.send((1, 1), pv("MAV2_POSITION", 4.0))  # the newer group name, explained by r2
    c4 = flow.send((1, 1), pv("SR0_PARAMS", 4.0))  # ALL does not set PARAMS: unexplained
    flow.send((255, 190), rds(3, 7, start=2))  # start_stop 2: ignored by ArduPilot
    c5 = flow.send((1, 1), pv("SR0_RC_CHAN", 7.0))  # so unexplained
    r6 = flow.send((255, 190), rds(3, 9, start=0))  # stop: stores 0
    c6 = flow.send((1, 1), pv("SR0_RC_CHAN", 0.0))
    flow.send((255, 190), rds(3, 5, target=(2, 1)))  # another system
    c7 = flow.send((1, 1), pv("SR0_RC_CHAN", 5.0))
    c8 = flow.send((1, 1), pv("FENCE_ENABLE", 0.0))  # security-relevant, nothing explains it
    log = analyse(frames_of(flow.write(tmp_path), dialect))
    got = [(e.frame, e.name, e.cause_frame, e.explanation) for e in log.timeline]
    assert got == [(c1, "SR0_RAW_SENS", r1, f"set by REQUEST_DATA_STREAM frame {r1}"),
                   (c2, "SR1_EXTRA1", r2, f"set by REQUEST_DATA_STREAM frame {r2}"),
                   (c3, "MAV2_POSITION", r2, f"set by REQUEST_DATA_STREAM frame {r2}"),
                   (c4, "SR0_PARAMS", None, None), (c5, "SR0_RC_CHAN", None, None),
                   (c6, "SR0_RC_CHAN", r6, f"set by REQUEST_DATA_STREAM frame {r6}"),
                   (c7, "SR0_RC_CHAN", None, None), (c8, "FENCE_ENABLE", None, None)]
    assert [(f.code, f.frames) for f in log.findings] == [("param-protection-disabled", (c8,))]
    texts = [param_event(e).text for e in log.timeline]
    assert texts[0].endswith(f"changed to 2 (was 1): set by REQUEST_DATA_STREAM frame {r1} (PARAM_VALUE)")
    assert "with no set to explain it" in texts[3] and "with no set to explain it" in texts[7]


def test_plane_stream_rates_are_explained(cli: Cli, real_captures: Path) -> None:
    path = real_captures / PLANE
    if not path.is_file():
        pytest.skip(f"{path} is absent")
    requests: list[tuple[int, str, int]] = []  # (frame, suffix, value) by ArduPilot's rule, from pymavlink
    for m in read(path):
        if m.name == "REQUEST_DATA_STREAM" and m.msg.target_system in (0, 1) and m.msg.start_stop in (0, 1):
            value = m.msg.req_message_rate if m.msg.start_stop else 0
            sid = m.msg.req_stream_id
            suffixes = list(AP_STREAMS.values()) + ["ADSB"] if sid == 0 else [AP_STREAMS[sid]] if sid in AP_STREAMS \
                else []
            requests += [(m.index + 1, s, value) for s in suffixes]
    assert len({r[0] for r in requests}) == 52  # the 52 REQUEST_DATA_STREAM of the capture, all to 1/1
    # each complete param.pck read: from its OpenFileRO to the end-of-file NAK (the last data sent)
    reads = [(r["open_index"] + 1, r["eof_nak"]["index"] + 1) for r in real_truth.ftp_reads(read(path))
             if r.get("eof_nak")]
    doc = cli.json("params", path)
    stream_rates = [e for e in doc["timeline"] if e["name"].startswith("SR0_")]
    assert len(stream_rates) == 34
    for e in stream_rates:
        suffix = e["name"][4:]
        mine = [(f, v) for f, s, v in requests if s == suffix and f < e["frame"]]
        matching = [f for f, v in mine if v == e["value"]]
        if matching:  # the latest earlier request of that stream with the value reported
            assert (e["cause_frame"], e["explanation"]) == (matching[-1],
                                                             f"set by REQUEST_DATA_STREAM frame {matching[-1]}"), e
        else:  # only a param.pck read across a request of that stream can hold the value from before it
            assert e["source"].startswith("FTP"), e
            start, end = max((a, b) for a, b in reads if a <= e["frame"])  # the read the change comes from
            during = [f for f, _v in mine if start <= f <= end]
            assert during and e["cause_frame"] == during[-1], e
            assert e["explanation"].startswith(f"the value from before REQUEST_DATA_STREAM frame {during[-1]}")
    # MIS_TOTAL by AP_Mission's rule (tests/analysis/test_params_missions.py): the last MISSION_COUNT (type 0)
    # or MISSION_CLEAR_ALL (type 0 or 255) to system 1 before the change, the value one it takes it to
    missions = [(m.index + 1, m.msg.count if m.name == "MISSION_COUNT" else 1) for m in read(path)
                if m.name in ("MISSION_COUNT", "MISSION_CLEAR_ALL") and m.msg.target_system == 1
                and m.msg.mission_type in ((0,) if m.name == "MISSION_COUNT" else (0, 255))]
    totals = [e for e in doc["timeline"] if e["name"] == "MIS_TOTAL"]
    for e in totals:
        last = [(f, top) for f, top in missions if f < e["frame"]][-1:]
        explained = bool(last) and 0 <= e["value"] <= last[0][1]
        assert e["cause_frame"] == (last[0][0] if explained else None), e
    assert [e["frame"] for e in totals if e["cause_frame"]] == [4977]  # Mission Planner's upload of 0 items
    others = [e for e in doc["timeline"] if not e["name"].startswith("SR0_") and e["name"] != "MIS_TOTAL"]
    assert others and all(e["explanation"] is None and e["cause_frame"] is None for e in others)
    assert doc["unexplained"] == len(others) + len(totals) - 1
    assert doc["findings"] == []  # no security-relevant parameter moved
    status, out, _ = cli("events", path)
    assert status == 0
    param_lines = [line for line in out.splitlines() if " SR0_" in line and "changed to" in line]
    assert len(param_lines) == 34 and not any("no set to explain it" in line for line in param_lines)
