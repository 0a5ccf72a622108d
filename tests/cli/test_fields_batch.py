"""`read -T fields` over column batches (mavscope.output.fields_batch) against the frame-by-frame writer.

The batch writer is the fast form of FieldsWriter: its lines must be the frame-by-frame writer's, byte for
byte, for every field it serves, on both engines. The reference here is FieldsWriter fed the session's
frames one by one (its own answers are held to tshark and to lines written by hand in
tests/crosscheck/test_tshark_fields.py and tests/cli/test_fields_output.py). Swept over every bundled
capture and every shared real one (the tiers keep two bundled and one real in `make test`), and over every
way of cutting a capture into batches (a record of several frames cut across two batches included).
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mavscope.fields.registry import BY_NAME, FieldRegistry
from mavscope.mavlink.frame import Frame
from mavscope.native.core import NATIVE, _native
from mavscope.output.fields_batch import UNSERVED, BatchFieldsWriter, join_cells, serves
from mavscope.output.fields_out import FieldsWriter, parse_format
from mavscope.output.timefmt import Clock
from mavscope.pipeline.batch import FrameBatch, Tables
from mavscope.pipeline.dissect import Anomaly
from mavscope.pipeline.options import PipelineOptions
from mavscope.pipeline.session import open_session
from tests.conftest import Cli
from tests.support.builders import attitude, heartbeat, mav2, statustext, write_udp_pcap

ROOT = Path(__file__).resolve().parents[2]
BUNDLED = sorted(p for p in (ROOT / "captures").iterdir() if p.suffix in (".pcap", ".pcapng", ".tlog", ".raw"))
REAL_DIR = ROOT.parent / "shared" / "real-captures"
REAL = sorted(p for p in REAL_DIR.iterdir() if p.suffix in (".pcap", ".pcapng", ".tlog", ".raw", ".bin")) \
    if REAL_DIR.is_dir() else []
# every registered field but the two the batch writer leaves to the frame-by-frame one, and payload fields
# of every form: one message's, a bare name of many messages, an array, a char array, a companion in a
# display unit, a container's field
HEADER = [n for n in BY_NAME if n not in UNSERVED]
PAYLOAD = ["ATTITUDE.roll", "HEARTBEAT.custom_mode", "time_boot_ms", "GPS_RAW_INT.satellites_visible",
           "STATUSTEXT.text", "PARAM_VALUE.param_id", "SERVO_OUTPUT_RAW.servo1_raw", "MISSION_ITEM_INT.x",
           "GLOBAL_POSITION_INT.lat_deg", "lat_deg", "alt_m", "COMMAND_LONG.command", "ftp.opcode",
           "FILE_TRANSFER_PROTOCOL.payload", "mavlink_proto.sysid", "mavlink_proto.GLOBAL_POSITION_INT_lat"]
FORMATS = [(), ("occurrence=f", "quote=d", "separator=,"), ("occurrence=l", "aggregator=/s", "quote=s")]


def _per_frame(path: Path, names: list[str], options: tuple[str, ...], environ: dict[str, str]) -> str:
    out = io.StringIO()
    with open_session(str(path), PipelineOptions(), environ=environ) as s:
        w = FieldsWriter(out, FieldRegistry(s.dialect), names, parse_format(options), Clock("r", s.t0))
        w.begin()
        for item in s.items:
            if type(item) is not Anomaly:
                w.frame(item)
        w.end()
    return out.getvalue()


def _batched(path: Path, names: list[str], options: tuple[str, ...], environ: dict[str, str]) -> str:
    out = io.StringIO()
    with open_session(str(path), PipelineOptions(), environ=environ) as s:
        w = BatchFieldsWriter(out, FieldRegistry(s.dialect), names, parse_format(options), Clock("r", s.t0),
                              native=s.engine == NATIVE)
        w.begin()
        for b in s.batches(lambda _item: None):
            w.batch(b)
        w.end()
    return out.getvalue()


def _names(dialect_names: FieldRegistry) -> list[str]:
    return [n for n in HEADER + PAYLOAD if dialect_names.lookup(n) is not None]


@pytest.mark.parametrize("engine", ["native", "pure"])
@pytest.mark.parametrize("path", BUNDLED + REAL, ids=lambda p: p.name)
def test_batch_lines_are_the_frame_by_frame_lines(path: Path, engine: str) -> None:
    environ = {"MAVSCOPE_PURE": "1"} if engine == "pure" else {}
    with open_session(str(path), PipelineOptions(), environ={}) as s:
        names = _names(FieldRegistry(s.dialect))
    want = _per_frame(path, names, (), environ)
    assert want.count("\n") > 0
    assert _batched(path, names, (), environ) == want
    for options in FORMATS[1:]:  # (the -E forms on a handful of fields)
        few = ["frame.number", "mavlink.seq", "ip.addr", "ATTITUDE.roll", "STATUSTEXT.text", "frame.src"]
        assert _batched(path, few, options, environ) == _per_frame(path, few, options, environ)


def _datagrams(tmp: Path) -> Path:
    v = mav2(1, 1)
    two = attitude(mav2(1, 1, 1), 10, 0.5) + attitude(mav2(1, 1, 2), 20, -0.25)
    three = heartbeat(mav2(1, 1, 3)) + statustext(mav2(1, 1, 4), 'x"y') + attitude(mav2(1, 1, 5), 30, 1.5)
    return write_udp_pcap(tmp / "d.pcap", [((f"10.0.0.{k % 3 + 1}", 14550 + k), ("10.0.0.9", 14580), p)
                                           for k, p in enumerate([heartbeat(v), two, three, two, heartbeat(v)])])


@settings(max_examples=60, deadline=None)
@given(cuts=st.lists(st.integers(0, 9), max_size=6), form=st.sampled_from(FORMATS))
def test_any_cut_into_batches_gives_the_same_lines(tmp_path_factory: pytest.TempPathFactory, cuts: list[int],
                                                   form: tuple[str, ...]) -> None:
    path = _datagrams(tmp_path_factory.mktemp("cut"))
    names = ["frame.number", "frame.index", "mavlink.seq", "roll", "STATUSTEXT.text", "udp.srcport", "ip.addr",
             "mavlink.msgname", "frame.time_relative"]
    with open_session(str(path), PipelineOptions(), environ={"MAVSCOPE_PURE": "1"}) as s:
        frames: list[Frame] = [f for f in s.items if type(f) is not Anomaly]
        dialect, t0 = s.dialect, s.t0
    want = io.StringIO()
    ref = FieldsWriter(want, FieldRegistry(dialect), names, parse_format(form), Clock("r", t0))
    for f in frames:
        ref.frame(f)
    ref.end()
    got = io.StringIO()
    w = BatchFieldsWriter(got, FieldRegistry(dialect), names, parse_format(form), Clock("r", t0),
                          native=_native is not None)
    tables = Tables()
    bounds = [0, *sorted(c for c in cuts if c <= len(frames)), len(frames)]
    for a, z in zip(bounds, bounds[1:]):
        w.batch(FrameBatch.of_frames(frames[a:z], tables))
    w.end()
    assert got.getvalue() == want.getvalue()
    # by hand: five datagrams of 1, 2, 3, 2, 1 frames make five lines
    assert got.getvalue().count("\n") == 5


_CELL = st.one_of(st.none(), st.text(alphabet=st.sampled_from('ab"\'é,\t§ '), max_size=4))


@st.composite
def _joins(draw: st.DrawFn) -> tuple[list[object], np.ndarray, bytes, str, str, str]:
    sizes = draw(st.lists(st.integers(1, 3), max_size=6))
    bounds = np.cumsum([0, *sizes]).astype(np.int64)
    rows, lines = int(bounds[-1]), len(sizes)
    cells: list[object] = []
    modes = bytearray()
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["ints", "coded", "rows", "cells", "f4", "i8"]))
        if kind == "ints":
            ints = draw(st.lists(st.integers(-(1 << 63), (1 << 63) - 1), min_size=rows, max_size=rows))
            cells.append(np.asarray(ints, np.int64))
        elif kind == "coded":
            texts = draw(st.lists(_CELL, min_size=1, max_size=4))
            ids = draw(st.lists(st.integers(0, len(texts) - 1), min_size=rows, max_size=rows))
            cells.append((texts, np.asarray(ids, np.int64)))
        elif kind == "f4":  # any float32 bits: NaNs, infinities, subnormals
            bits = draw(st.lists(st.integers(0, (1 << 32) - 1), min_size=rows, max_size=rows))
            present = draw(st.lists(st.booleans(), min_size=rows, max_size=rows))
            cells.append(("f4", np.asarray(bits, np.uint32).view(np.float32), np.asarray(present, np.bool_)))
        elif kind == "i8":
            ints = draw(st.lists(st.integers(-(1 << 63), (1 << 63) - 1), min_size=rows, max_size=rows))
            present = draw(st.lists(st.booleans(), min_size=rows, max_size=rows))
            cells.append(("i8", np.asarray(ints, np.int64), np.asarray(present, np.bool_)))
        elif kind == "rows":
            cells.append((draw(st.lists(_CELL, min_size=rows, max_size=rows)), None))
        else:
            cells.append(draw(st.lists(_CELL, min_size=lines, max_size=lines)))
        modes += draw(st.sampled_from([b"r", b"f", b"l", b"a"]))
    quote = draw(st.sampled_from(["", '"', "'"]))
    return cells, bounds, bytes(modes), draw(st.sampled_from(["\t", ",", " ", "§"])), quote, \
        draw(st.sampled_from([",", " ", "§", '"']))


@pytest.mark.skipif(_native is None, reason="the C extension is not built")
@settings(max_examples=400, deadline=None)
@given(case=_joins())
def test_the_native_joiner_is_the_reference_joiner(case: tuple[list[object], np.ndarray, bytes, str, str, str]
                                                    ) -> None:
    assert _native is not None
    assert _native.join_fields(*case) == join_cells(*case)


def test_the_joiner_by_hand() -> None:
    # two records (rows 0..1 and 2), a number column whose record joins all, a text column of a cell per
    # record with a quote inside: written out by hand
    cells = [np.asarray([7, -8, 9], np.int64), ['a"b', None]]
    want = '"7;-8"\t"a""b"\n"9"\t\n'
    args = (cells, np.asarray([0, 2, 3], np.int64), b"aa", "\t", '"', ";")
    assert join_cells(*args) == want
    last = (cells, np.asarray([0, 2, 3], np.int64), b"la", "\t", "", ";")
    assert join_cells(*last) == '-8\ta"b\n9\t\n'
    # a coded column: texts x, None, y; rows 0..2 have x, None, y: the record's first row (r), the first and
    # last values (f, l: None has none), all of them (a)
    coded = [(["x", None, "y"], np.asarray([0, 1, 2], np.int64))] * 4
    both = (coded, np.asarray([0, 2, 3], np.int64), b"rfla", ",", "", ";")
    assert join_cells(*both) == "x,x,x,x\ny,y,y,y\n"
    late = ([(["x", None, "y"], np.asarray([1, 2, 1], np.int64))] * 4, np.asarray([0, 2, 3], np.int64), b"rfla",
            ",", "", ";")
    assert join_cells(*late) == ",y,y,y\n,,,\n"
    if _native is not None:
        for case in (args, last, both, late):
            assert _native.join_fields(*case) == join_cells(*case)


def test_count_stops_inside_a_record_as_frame_by_frame(cli: Cli, tmp_path: Path) -> None:
    path = str(_datagrams(tmp_path))
    # -c 4: the heartbeat of record 1, both frames of record 2, the first of record 3's three (seq 3)
    got = cli("read", path, "-T", "fields", "-e", "frame.number", "-e", "mavlink.seq", "-c", "4")
    assert got.status == 0, got.err
    assert got.out.splitlines() == ["1\t0", "2\t1,2", "3\t3"]


def test_the_fields_that_need_every_record_keep_the_frame_by_frame_writer() -> None:
    assert serves(["frame.number", "ATTITUDE.roll"])
    assert not serves(["frame.number", "frame.time_delta"]) and not serves(["frame.time_delta_displayed"])
