"""Hostile exchanges (random FTP headers, paths, offsets up to 4 GiB, sizes past the data field; LOG_DATA
and image handshakes with absurd sizes) built by pymavlink with valid CRCs, so that they reach the
trackers: no exception, the bytes held stay within the limits, and every object written lands as a
regular file directly inside the output directory."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as v2
from pymavlink.mavftp_op import FTP_OP

from mavscope.analysis.objects import Limits, ObjectTracker, analyse
from mavscope.analysis.params import ParamTracker
from mavscope.analysis.runs import missing_runs
from mavscope.mavlink.dialect import Dialect
from mavscope.output.objects_out import ObjectWriter
from tests.support.ftpflows import Flow, frames_of

LIMITS = Limits(max_object=4096, max_total=16384, max_open=4, max_objects=20, max_ranges=16, max_frames=8)
paths = st.one_of(st.sampled_from(["../../etc/passwd", "/APM/scripts/x.lua", "@PARAM/param.pck", "a/../../b",
                                   "x" * 239, "\x1b[31mred", "C:\\boot.ini"]),
                  st.text(max_size=40))
offsets = st.one_of(st.integers(0, 600), st.integers(0, 0xFFFF_FFFF))
ftp_op = st.tuples(st.booleans(), st.integers(0, 65535), st.integers(0, 3),
                   st.sampled_from([1, 2, 3, 4, 5, 6, 7, 8, 11, 13, 14, 15, 128, 129, 200]), st.integers(0, 255),
                   st.sampled_from([0, 3, 4, 5, 6, 7, 15, 77]), st.integers(0, 1), offsets, st.binary(max_size=239),
                   paths)
other = st.one_of(
    st.tuples(st.just("log"), st.integers(0, 3), offsets, st.integers(0, 255), st.binary(max_size=90)),
    st.tuples(st.just("hs"), st.integers(0, 0xFFFF_FFFF), st.integers(0, 65535), st.integers(0, 255)),
    st.tuples(st.just("enc"), st.integers(0, 65535), st.binary(max_size=253)),
    st.tuples(st.just("entry"), st.integers(0, 3), st.integers(0, 0xFFFF_FFFF)),
)


def build(ops: list, extra: list) -> Flow:
    flow = Flow()
    for from_gcs, seq, session, opcode, size, req, burst, offset, data, path in ops:
        body = path.encode("utf-8", "surrogatepass")[:239] if opcode in (3, 4, 6, 8, 11, 13, 14) else data
        op = FTP_OP(seq, session, opcode, size, req, burst, offset, bytearray(body))
        if from_gcs:
            flow.ftp(flow.gcs_addr, flow.vehicle_addr, op)
        else:
            flow.ftp(flow.vehicle_addr, flow.gcs_addr, op)
    veh = flow.vehicle_addr
    for item in extra:
        if item[0] == "log":
            _, log_id, ofs, count, data = item
            flow.send(veh, v2.MAVLink_log_data_message(log_id, ofs, count, list(data.ljust(90, b"\0"))))
        elif item[0] == "hs":
            _, size, packets, payload = item
            flow.send(veh, v2.MAVLink_data_transmission_handshake_message(0, size, 64, 64, packets, payload, 50))
        elif item[0] == "enc":
            flow.send(veh, v2.MAVLink_encapsulated_data_message(item[1], list(item[2].ljust(253, b"\0"))))
        else:
            flow.send(veh, v2.MAVLink_log_entry_message(item[1], 4, 3, 0, item[2]))
    return flow


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                 HealthCheck.too_slow])
@given(st.lists(ftp_op, max_size=25), st.lists(other, max_size=15))
def test_hostile_exchanges(tmp_path: Path, dialect: Dialect, ops: list, extra: list) -> None:
    work = Path(tempfile.mkdtemp(dir=tmp_path))  # one per example (hypothesis reuses the fixture)
    frames = frames_of(build(ops, extra).write(work), dialect)
    tracker = ObjectTracker(LIMITS)
    params = ParamTracker(LIMITS)
    out = work / "out"
    writer = ObjectWriter(str(out))
    try:
        for f in frames:
            tracker.feed(f)
            params.feed(f)
            assert tracker.ctx.budget.held <= LIMITS.max_total + LIMITS.max_object
            for rec in tracker.take():
                writer.write(rec)
        log = tracker.finish()
        for rec in tracker.take():
            writer.write(rec)
        params.finish()
    finally:
        writer.close()
    assert len(log.objects) <= LIMITS.max_objects
    assert all(o.size <= LIMITS.max_object and len(o.frames) <= LIMITS.max_frames for o in log.objects)
    for entry in os.scandir(out):
        assert entry.is_file(follow_symlinks=False) and not entry.name.startswith(".")
    assert sorted(e.name for e in os.scandir(out)) == sorted(o.file for o in log.objects)


@given(st.sets(st.integers(-3, 70)), st.integers(0, 64))
def test_missing_runs_are_the_numbers_not_present(present: set[int], count: int) -> None:
    """Against the plain scan of every number below `count`."""
    runs = missing_runs(present, count)
    assert [n for a, b in runs for n in range(a, b + 1)] == [n for n in range(count) if n not in present]
    assert all(b + 1 < c for (_, b), (c, _) in zip(runs, runs[1:]))  # maximal runs


def test_an_image_of_65535_packets_lists_every_missing_one(tmp_path: Path, dialect: Dialect) -> None:
    """A handshake announcing 65,535 packets of 253 bytes and one packet (seqnr 5) received: missing are
    0-4 and 6-65534 (by hand). The packets were scanned one by one at the end (65,535 steps per image,
    4,000 such images took 266 s), and only the first 4,096 missing ones were listed: [[0, 4], [6, 4096]]."""
    flow = Flow()
    veh = flow.vehicle_addr
    flow.send(veh, v2.MAVLink_data_transmission_handshake_message(0, 65535 * 253, 64, 64, 65535, 253, 50))
    flow.send(veh, v2.MAVLink_encapsulated_data_message(5, list(b"p" * 253)))
    log = analyse(frames_of(flow.write(tmp_path), dialect), dialect)
    [image] = log.objects
    assert image.details["missing_packets"] == [[0, 4], [6, 65534]]
    assert image.details["packets_received"] == 1
