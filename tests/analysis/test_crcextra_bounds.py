"""The dialect-mismatch groups' bound (issue 35, item 1 for crcextra.Mismatches; docs/security.md, "Bounds").

A group is (sender, message id, the CRC_EXTRA its bad CRC fits). Crafted bad-CRC frames can each fit a new
group (a new sender each), and every group held memory for the rest of the capture. Now MAX_GROUPS are
followed; past it the newest group of one frame goes for the new one, said as a `capacity` finding, and a
group of two frames or more (an established mismatch) stays. The frames are built with pymavlink and their
CRCs computed by the test with a CRC_EXTRA it chooses (test_dialect_mismatch.with_extra: pymavlink's x25crc).
"""

from __future__ import annotations

import json
from pathlib import Path

from pymavlink.dialects.v20 import all as v2

from mavscope.analysis import crcextra
from mavscope.analysis.expert import BadCrcBursts, Expert
from mavscope.capture.detect import open_capture
from mavscope.mavlink.dialect import load_dialect
from mavscope.pipeline.dissect import Anomaly, Dissector
from tests.analysis.test_dialect_mismatch import with_extra
from tests.conftest import Cli
from tests.support import flows

PURE, NATIVE = {"MAVSCOPE_PURE": "1"}, {"MAVSCOPE_PURE": "0"}
FLOOD = 5000


def flood_capture(tmp_path: Path) -> str:
    """Records 1-10: ATTITUDE frames (id 30) of the vehicle 1/1 with CRC_EXTRA 77 (all.xml's is 39), 2 s apart.
    Records 11-5010: HEARTBEATs (id 0, CRC_EXTRA 50) with CRC_EXTRA 77, each from its own sender (flood frame
    i from 2 + i // 200 / 1 + i % 200), 1 ms apart: a new group each. Records 5011-5020: 10 more ATTITUDE
    frames of 1/1 with CRC_EXTRA 77."""
    vehicle = flows.Sender(1, 1)
    entries = [(flows.T0 + 2 * i, with_extra(vehicle.pack(v2.MAVLink_attitude_message(i, 0, 0, 0, 0, 0, 0)), 77))
               for i in range(10)]
    for i in range(FLOOD):
        s = flows.Sender(2 + i // 200, 1 + i % 200)
        entries.append((flows.T0 + 30 + 0.001 * i, with_extra(s.pack(flows.heartbeat()), 77)))
    entries += [(flows.T0 + 100 + 2 * i, with_extra(vehicle.pack(v2.MAVLink_attitude_message(i, 0, 0, 0, 0, 0, 0)),
                                                     77)) for i in range(10)]
    return flows.write_tlog(tmp_path, entries)


def test_a_flood_of_groups_is_bounded_said_and_keeps_the_mismatch(cli: Cli, tmp_path: Path) -> None:
    """By hand: the vehicle's group holds 10 frames before the flood. MAX_GROUPS is 4,096: it and flood groups
    1-4,095 fill the table; flood frames 4,096-5,000 (records 4,106-5,010) each give up the newest group of one
    frame, the flood frame's before it: 905 give-ups, said at the 1st, 2nd, 4th, ... 512th (records 4,105 + 1,
    2, 4, ..., 512). The last said (record 4,617) gave up the group of record 4,616: flood frame 4,605, from
    25/6. The vehicle's 20 frames are the mismatch (the old code kept all 5,001 groups and said nothing)."""
    assert crcextra.MAX_GROUPS == 4096
    path = flood_capture(tmp_path)
    doc = cli.json("stats", path, environ=PURE)
    (m,) = [f for f in doc["findings"] if f["code"] == "dialect-mismatch"]
    assert "20 frame(s) of message id 30 from 1/1" in m["message"] and "fits CRC_EXTRA 77" in m["message"]
    (capacity,) = [f for f in doc["findings"] if f["code"] == "capacity"]
    assert capacity["frames"] == [4105 + (1 << k) for k in range(10)]
    assert capacity["message"].startswith(
        "dialect-mismatch groups of bad-CRC frames (at most 4,096 (sender, id, CRC_EXTRA that fits) followed): "
        "905 given up (905 frames); the last said: the group of message id 0 from 25/6 fitting CRC_EXTRA 77 "
        "(1 frame) given up for a new one")
    audit = cli("audit", path, "--json", environ=PURE)
    found = json.loads(audit.out)["findings"]
    assert [f["frames"] for f in found if f["code"] == "capacity"] == [capacity["frames"]] and audit.status == 1
    for argv in (("stats", path, "--json"), ("audit", path, "--json"), ("audit", path)):
        assert cli(*argv, environ=NATIVE) == cli(*argv, environ=PURE), argv
    # and the memory: 4,096 groups held at the end, the vehicle's among them
    dialect = load_dialect()
    expert = Expert(dialect)
    with open_capture(path) as reader:
        for item in Dissector(dialect).run(reader):
            if type(item) is not Anomaly:
                expert.add(item)
    (bursts,) = [d for d in expert.detectors if isinstance(d, BadCrcBursts)]
    assert len(bursts.mismatches.fits) == 4096 and (1, 1, 30, 77) in bursts.mismatches.fits
    assert len(bursts.mismatches.runs) <= 4096


def test_when_every_group_is_established_the_new_one_goes(tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """MAX_GROUPS lowered to 2: the vehicle's ATTITUDE frames with CRC_EXTRA 77 (records 1-10) and 2/1's
    HEARTBEATs with CRC_EXTRA 77 (records 11-20) make two groups of 10 frames, none of one frame; the frame of
    a third sender (record 21, a new group) is then the one not followed, said, and both groups stay."""
    monkeypatch.setattr(crcextra, "MAX_GROUPS", 2)
    vehicle, other, third = flows.Sender(1, 1), flows.Sender(2, 1), flows.Sender(3, 1)
    entries = [(flows.T0 + i, with_extra(vehicle.pack(v2.MAVLink_attitude_message(i, 0, 0, 0, 0, 0, 0)), 77))
               for i in range(10)]
    entries += [(flows.T0 + 10 + i, with_extra(other.pack(flows.heartbeat()), 77)) for i in range(10)]
    entries.append((flows.T0 + 30, with_extra(third.pack(flows.heartbeat()), 77)))
    path = flows.write_tlog(tmp_path, entries)
    dialect = load_dialect()
    m = crcextra.Mismatches()
    with open_capture(path) as reader:
        for item in Dissector(dialect).run(reader):
            if type(item) is not Anomaly:
                m.add(item)
    assert set(m.fits) == {(1, 1, 30, 77), (2, 1, 0, 77)}
    (f,) = [x for x in m.findings(dialect) if x.code == "capacity"]
    assert f.frames == (21,) and "the frame of message id 0 from 3/1 fitting CRC_EXTRA 77 not followed" in f.message


def test_audit_writes_each_findings_frames_once_from_its_frames(cli: Cli, tmp_path: Path) -> None:
    """No finding's message lists its frames (--json: they are `frames`); audit's text writes them once after
    the message, the first 8 and how many more (notes.finding_line): the capacity finding above, its 10
    records, as "(frames 4106, 4107, 4109, 4113, 4121, 4137, 4169, 4233 and 2 more)"."""
    path = flood_capture(tmp_path)
    doc = json.loads(cli("audit", path, "--json", environ=PURE).out)
    assert not [f for f in doc["findings"] if "(frames " in f["message"]]
    out = cli("audit", path, environ=PURE).out
    lines = [line for line in out.splitlines() if line.startswith("[")]
    assert all(line.count("(frames ") == 1 for line in lines)
    (capacity,) = [line for line in lines if "] capacity: " in line]
    assert capacity.endswith("(frames 4106, 4107, 4109, 4113, 4121, 4137, 4169, 4233 and 2 more)")
