"""The native source feeds the findings' analyses in bulk (mavscope/export/findings_feed.py): the state it
leaves them in must be the state the pure one-frame-at-a-time pass leaves, not only the findings (most
captures do not reach the limits and rare paths where a difference would show in a finding).

The pure side here is the reference written out: the session's frames, each given to `Analyses.add`. The
state compared: the audit's first plaintexts and signing-stream targets, the object and parameter
trackers' activity clocks, and the expert's findings (its detectors are the `stats` accumulator's on the
native side). `Targets.add_run` is held to the calls it stands for, on hypothesis-drawn sequences.
"""

from __future__ import annotations

import dataclasses
import math
import struct
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mavscope.analysis.objects import ObjectTracker
from mavscope.analysis.objects.tracker import FTP_MESSAGE, TRACKED_MESSAGES
from mavscope.analysis.params.tracker import ParamTracker
from mavscope.capture.detect import open_capture
from mavscope.export import record_batches
from mavscope.export.options import ExportOptions, dialect_for
from mavscope.export.pure import Analyses
from mavscope.mavlink.dialect import Dialect, MessageDef
from mavscope.mavlink.frame import CrcStatus, Frame, Signature, new_frame
from mavscope.native import export as native
from mavscope.native.columns import decoded, message_plan
from mavscope.pipeline.dissect import Anomaly
from mavscope.pipeline.options import PipelineOptions
from mavscope.pipeline.session import make_security_stage, open_session
from mavscope.security.passphrase import MAX_TARGETS, Targets
from tests.conftest import CAPTURES
from tests.native import build as nh
from tests.native.engines import capture_file
from tests.native.test_generated import FEWER, capture

pytestmark = pytest.mark.skipif(native._native is None, reason="the native extension is not built")

PATHS = sorted(p for p in CAPTURES.iterdir() if p.suffix not in (".md", ".json"))


def pure_analyses(path: str | Path, pipeline: PipelineOptions) -> Analyses:
    dialect = dialect_for(pipeline)
    a = Analyses(dialect)
    with open_session(str(path), pipeline, dialect=dialect) as session:
        for item in session.items:
            if type(item) is not Anomaly:
                a.add(item)
    return a


def native_analyses(path: str | Path, pipeline: PipelineOptions) -> Analyses:
    dialect = dialect_for(pipeline)
    with open_capture(str(path)) as reader:
        kind = reader.kind
    export = native._Export(str(path), kind, "0" * 64, ExportOptions(pipeline=pipeline), dialect,
                            make_security_stage(pipeline))
    for _ in export.run(None):
        pass
    export.settle()
    return export.analyses


def _one(a: Analyses, kind: type) -> object:
    return next(d for d in a.expert.detectors if isinstance(d, kind))


def state(a: Analyses) -> dict[str, object]:
    return {
        # the expert's detectors are the `stats` accumulator's on the native side (their internal state is
        # held to the pure pass's by tests/native's stats tests): their findings, every field of them
        "findings": [dataclasses.asdict(f) for f in a.expert.findings()],
        "plain": sorted(a.audit.keystreams.plain.items()),
        "targets": list(a.audit.targets.seen.items()),
        "target_frames": [(s, [(f.record, f.index, f.raw) for f in fs]) for s, fs in a.audit.targets.frames.items()],
        # the unsigned frames of senders before their first signed frame (the native feed's in bulk)
        "downgrades": (sorted(a.audit_pass.downgrades.signers), a.audit_pass.downgrades.listed,
                       [(s, e.v1, e.v2, e.listed) for s, e in a.audit_pass.downgrades.early.items()]),
        "ticks": (a.objects.ctx.tick, a.params.objects.ctx.tick),
        "now": a.params.now,
        # what the parameter tracker holds (the native source leaves out HEARTBEATs that change nothing)
        "encodings": a.params.encodings,
        "components": {k: dataclasses.asdict(c) for k, c in a.params.components.items()},
        "timeline": [dataclasses.asdict(e) for e in a.params.timeline],
    }


def _nan_named(value: object) -> object:
    """`value` with every float NaN replaced by the string "NaN" (a NaN is unequal to itself, and a parameter
    or a finding may well hold one: two runs' states would differ though the same)."""
    if isinstance(value, float) and math.isnan(value):
        return "NaN"
    if isinstance(value, dict):
        return {k: _nan_named(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(_nan_named(v) for v in value)
    return value


def same_state(path: str | Path, pipeline: PipelineOptions | None = None) -> None:
    pipeline = pipeline or PipelineOptions()
    want, got = (_nan_named(state(a(path, pipeline))) for a in (pure_analyses, native_analyses))
    for key in want:
        assert got[key] == want[key], key


@pytest.fixture(params=[65_536, 3], ids=["window", "window3"])
def windows(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(native, "WINDOW_FRAMES", request.param)


@pytest.mark.parametrize("path", PATHS, ids=lambda p: p.name)
def test_the_analyses_are_left_as_the_pure_pass_leaves_them(path: Path, windows: None) -> None:
    same_state(path)
    same_state(path, PipelineOptions(use_leaked_keys=True))


def test_real_captures_leave_the_same_state(real_captures: Path) -> None:
    for path in sorted(p for p in real_captures.iterdir() if p.suffix != ".md"):
        same_state(path)


@FEWER
@given(capture())
def test_generated_captures_leave_the_same_state(data: bytes) -> None:
    with capture_file(data) as path:
        same_state(path)


def _signed(record: int, sysid: int, link: int) -> Frame:
    return new_frame(record, 1, None, "udp", None, None, 0, bytes([record & 255]), 2, 0, 1, 0, 0, sysid, 1, 0, 0,
                     CrcStatus.OK, None, Signature(link, record, b"\x00" * 6), (), None)


@given(st.lists(st.tuples(st.integers(1, 3), st.integers(0, 1)), max_size=300), st.integers(0, 3))
def test_add_run_is_as_many_adds(streams: list[tuple[int, int]], preset: int) -> None:
    """Runs of signed frames per stream, streams in the order of their first frames, equal the adds one by
    one; also with the table of streams full (MAX_TARGETS) before."""
    frames = [_signed(i + 1, s, link) for i, (s, link) in enumerate(streams)]
    want, got = Targets(), Targets()
    for t in (want, got):
        for k in range(MAX_TARGETS - preset if preset else 0):
            t.seen[(200, k % 256, k // 256)] = 1
    for f in frames:
        want.add(f)
    order: dict[tuple[int, int, int], list[Frame]] = {}
    for f in frames:
        assert f.signature is not None
        order.setdefault((f.sysid, f.compid, f.signature.link_id), []).append(f)
    for stream, fs in order.items():
        got.add_run(stream, len(fs), fs.__getitem__)
    assert got.seen == want.seen
    assert list(got.seen) == list(want.seen)
    assert {k: [f.record for f in v] for k, v in got.frames.items()} == {k: [f.record for f in v]
                                                                       for k, v in want.frames.items()}


def test_a_sender_signing_only_undecoded_messages_counts_as_signing(dialect: Dialect) -> None:
    """System 1 signs its ATTITUDE frames only (no detector decodes ATTITUDE: the native source builds no
    Frame for them); system 255 sends it an unsigned COMMAND_LONG: a downgrade, `unsigned-command`, by
    construction of the capture (and `command-without-heartbeat`: 255 sent none)."""
    att, cmd = dialect.by_name["ATTITUDE"], dialect.by_name["COMMAND_LONG"]
    frames = [nh.frame_v2(att, att.id, bytes(att.length), i, 1, 1, iflags=1, timestamp=1000 + i) for i in range(3)]
    payload = bytearray(cmd.length)
    payload[next(f for f in cmd.fields if f.name == "target_system").offset] = 1
    frames.append(nh.frame_v2(cmd, cmd.id, bytes(payload), 0, 255, 190))
    packets = [nh.link("ethernet", nh.ipv4(b"\x0a\0\0\x01", b"\x0a\0\0\x02", 17, nh.udp(14550, 14555, f)), False)
               for f in frames]
    data = nh.pcap([(1_700_000_000 + i, 0, p) for i, p in enumerate(packets)], nh.LINKTYPES["ethernet"])
    with capture_file(data) as path:
        for source in ("python", "native"):
            found = [r for b in record_batches(path, ExportOptions(source=source, tables=frozenset({"findings"})))
                     for r in b.to_pylist()]
            codes = sorted(r["code"] for r in found if r["source"] == "stats")
            assert codes == ["command-without-heartbeat", "unsigned-command"], source
        same_state(path)


def test_the_object_trackers_clock_reads_as_in_the_pure_pass(monkeypatch: pytest.MonkeyPatch) -> None:
    """The activity clock (`tick`: frames seen) each frame of a tracked message meets, in both passes."""
    seen: list[tuple[bool, int, int, int]] = []  # (the parameter tracker's own, record, index, tick)
    feed = ObjectTracker.feed

    def spy(self: ObjectTracker, f: Frame, fields: dict[str, object] | None = None) -> None:
        name = f.msgdef.name if f.msgdef is not None else None
        if name == FTP_MESSAGE or (name in TRACKED_MESSAGES and not self.ftp_only):  # what each one reads
            seen.append((self.ftp_only, f.record, f.index, self.ctx.tick))
        feed(self, f, fields)

    monkeypatch.setattr(ObjectTracker, "feed", spy)
    for path in (CAPTURES / "ftp_lua_upload.pcap", CAPTURES / "log_download.pcap", CAPTURES / "ftp_params.pcap"):
        seen.clear()
        pure_analyses(path, PipelineOptions())
        want = sorted(seen, key=lambda s: s[0])  # each tracker's calls in their order
        seen.clear()
        native_analyses(path, PipelineOptions())
        assert want and sorted(seen, key=lambda s: s[0]) == want


SIMPLE = [md for md in sorted(dialect_for(PipelineOptions()).messages.values(), key=lambda m: m.id)
          if all(fd.array_length == 0 and fd.type != "char" for fd in md.fields)]


def _bits_of(fields: dict[str, object]) -> list[tuple[str, object]]:
    return [(k, struct.pack("<d", v) if isinstance(v, float) else v) for k, v in fields.items()]


@given(st.sampled_from(SIMPLE), st.data())
def test_payload_rows_decode_as_the_message_decoder_decodes(md: MessageDef, data: st.DataObject) -> None:
    """`native_columns.decoded` (numpy over zero-extended payload rows) gives `md.decode`'s dicts: the same
    keys in the same order, the same ints, the same float bits (signalling NaNs quieted alike)."""
    snan = st.sampled_from([b"\x01\x00\x80\x7f", b"\x01\x00\x80\xff", b"\x00\x00\xc0\x7f", b"\x00\x00\x00\x80"])
    rows = data.draw(st.lists(st.one_of(st.binary(min_size=md.length, max_size=md.length),
                                        snan.map(lambda b: (b * 64)[:md.length])), min_size=1, max_size=20))
    plan = message_plan(md, dialect_for(PipelineOptions()))
    got = decoded(plan, b"".join(rows), len(rows))
    assert [_bits_of(d) for d in got] == [_bits_of(md.decode(r)) for r in rows]


@pytest.mark.parametrize("window", [65_536, 3])
def test_heartbeats_left_out_change_nothing_the_parameter_tracker_holds(
        window: int, dialect: Dialect, monkeypatch: pytest.MonkeyPatch) -> None:
    """System 1 switches between PX4 (bytewise parameters) and ArduPilot (C-cast) HEARTBEATs, repeats them, sends
    GCS-typed ones, one with a bad CRC and one after stray bytes (both handed back: the latter says ArduPilot
    between two PX4 ones), each followed by PARAM_VALUEs whose INT32 bytes read differently in the two
    encodings: the parameter tracker's state (encodings, values, timeline) must be the pure pass's, so the
    HEARTBEATs the native source leaves out must be exactly those that change nothing."""
    monkeypatch.setattr(native, "WINDOW_FRAMES", window)
    hb, pv = dialect.by_name["HEARTBEAT"], dialect.by_name["PARAM_VALUE"]

    def heartbeat(autopilot: int, kind: int) -> bytes:  # a payload in the dialect's layout, for nh.frame_v2
        payload = bytearray(hb.length)
        payload[hb.field("type").offset] = kind  # type: ignore[union-attr]
        payload[hb.field("autopilot").offset] = autopilot  # type: ignore[union-attr]
        return bytes(payload)

    def param(value: bytes) -> bytes:
        payload = bytearray(pv.length)
        at = pv.field("param_value").offset  # type: ignore[union-attr]
        payload[at:at + 4] = value
        payload[pv.field("param_id").offset:][:4] = b"RATE"  # type: ignore[union-attr]
        payload[pv.field("param_type").offset] = 6  # MAV_PARAM_TYPE_INT32  # type: ignore[union-attr]
        return bytes(payload)

    px4, apm, gcs = heartbeat(12, 2), heartbeat(3, 2), heartbeat(8, 6)
    script = [(hb, px4), (pv, param(b"\x05\0\0\0")), (hb, px4), (hb, apm), (pv, param(b"\0\0\xa0\x40")),
              (hb, apm), (hb, gcs), (hb, apm), (pv, param(b"\x07\0\0\0")), (hb, px4), (hb, "bad"), (hb, px4),
              (pv, param(b"\0\0\xa0\x40")), (hb, "stray"), (hb, px4), (pv, param(b"\x05\0\0\0")), (hb, apm),
              (hb, apm), (pv, param(b"\x05\0\0\0"))]
    frames = []
    for seq, (md, payload) in enumerate(script):
        if payload == "bad":
            f = bytearray(nh.frame_v2(md, md.id, apm, seq, 1, 1))
            f[-1] ^= 0xFF  # the CRC
            frames.append(bytes(f))
        elif payload == "stray":
            frames.append(b"\x00\x01" + nh.frame_v2(md, md.id, apm, seq, 1, 1))
        else:
            frames.append(nh.frame_v2(md, md.id, payload, seq, 1, 1))  # type: ignore[arg-type]
    packets = [nh.link("ethernet", nh.ipv4(b"\x0a\0\0\x01", b"\x0a\0\0\x02", 17, nh.udp(14550, 14555, f)), False)
               for f in frames]
    data = nh.pcap([(1_700_000_000 + i, 0, p) for i, p in enumerate(packets)], nh.LINKTYPES["ethernet"])
    with capture_file(data) as path:
        want = state(pure_analyses(path, PipelineOptions()))
        assert [e["value"] for e in want["timeline"]] and want["encodings"]  # the capture says something
        same_state(path)


@pytest.mark.parametrize("window", [65_536, 3])
@pytest.mark.parametrize("kind", ["pcap", "tlog"])
def test_param_values_read_from_payload_rows_leave_the_same_state(
        window: int, kind: str, dialect: Dialect, monkeypatch: pytest.MonkeyPatch) -> None:
    """The native source gives clean PARAM_VALUEs to the parameter tracker from their payload rows, without a
    Frame (`NativeFeed._param_values`). Reports that change values, signed (no key: `no-key`) and unsigned,
    from two UDP endpoints (or a tlog: no endpoint, the link is the transport), MAVLink 1 and 2, names with
    undecodable bytes, an embedded NUL and all 16 characters, a payload cut short (MAVLink 2's trailing
    zeros), a PARAM_SET they answer, and one with a bad CRC (handed back, so built and given to `feed`): the
    tracker's state must be the pure pass's, and `feed` must not have been given the clean ones."""
    monkeypatch.setattr(native, "WINDOW_FRAMES", window)
    pv, ps = dialect.by_name["PARAM_VALUE"], dialect.by_name["PARAM_SET"]

    def put(md: MessageDef, payload: bytearray, name: str, value: bytes) -> None:
        fd = md.field(name)
        assert fd is not None
        payload[fd.offset:fd.offset + len(value)] = value

    def param(pid: bytes, value: float, ptype: int = 9, count: int = 7) -> bytes:
        payload = bytearray(pv.length)
        put(pv, payload, "param_id", pid)
        put(pv, payload, "param_value", struct.pack("<f", value))
        put(pv, payload, "param_count", struct.pack("<H", count))
        put(pv, payload, "param_type", bytes([ptype]))
        return bytes(payload)

    def param_set(pid: bytes, value: float) -> bytes:
        payload = bytearray(ps.length)
        put(ps, payload, "param_id", pid)
        put(ps, payload, "param_value", struct.pack("<f", value))
        put(ps, payload, "target_system", b"\x01")
        put(ps, payload, "target_component", b"\x01")
        put(ps, payload, "param_type", b"\x09")
        return bytes(payload)

    # (frame bytes, from the vehicle's endpoint)
    script: list[tuple[bytes, bool]] = []
    for seq in range(12):  # system 2 signs all it sends (an unsigned frame of a signing system has a note)
        script.append((nh.frame_v2(pv, pv.id, param(b"RATE_RLL_P", 0.1 * seq), seq, 1, 1), True))
        script.append((nh.frame_v2(pv, pv.id, param(b"RATE_RLL_P", 0.2 * seq), seq, 2, 1, iflags=1, link_id=1,
                                   timestamp=seq), True))
        script.append((nh.frame_v2(pv, pv.id, param(b"\xffBAD\xfe", seq, 6, 9 + seq), seq, 1, 2), seq % 2 == 0))
    script += [
        (nh.frame_v1(pv, param(b"A\0B", 1.5), 20, 1, 1), True),
        (nh.frame_v1(pv, param(b"A\0B", 2.5), 21, 1, 1), True),
        (nh.frame_v2(pv, pv.id, param(b"SIXTEEN_CHARS_ID", 3.0), 22, 1, 1), True),
        (nh.frame_v2(pv, pv.id, param(b"SIXTEEN_CHARS_ID", 4.0), 23, 1, 1), True),
        (nh.frame_v2(pv, pv.id, param(b"CUT", 5.0, 0).rstrip(b"\0"), 24, 1, 1), True),
        (nh.frame_v2(pv, pv.id, param(b"CUT", 6.0, 0).rstrip(b"\0"), 25, 1, 1), True),
        (nh.frame_v2(ps, ps.id, param_set(b"RATE_RLL_P", 0.25), 26, 255, 190), False),
        (nh.frame_v2(pv, pv.id, param(b"RATE_RLL_P", 0.25), 27, 1, 1), True),
    ]
    bad = bytearray(nh.frame_v2(pv, pv.id, param(b"RATE_RLL_P", 9.0), 28, 1, 1))
    bad[-1] ^= 0xFF
    script += [(bytes(bad), True), (nh.frame_v2(pv, pv.id, param(b"RATE_RLL_P", 0.5), 29, 1, 1), True)]
    if kind == "tlog":
        data = nh.tlog([(1_700_000_000_000_000 + 1000 * i, f) for i, (f, _) in enumerate(script)])
    else:
        vehicle, gcs = b"\x0a\0\0\x01", b"\x0a\0\0\x02"
        packets = [nh.link("ethernet", nh.ipv4(vehicle if v else gcs, gcs if v else vehicle, 17,
                                               nh.udp(14550 if v else 14555, 14555 if v else 14550, f)), False)
                   for f, v in script]
        data = nh.pcap([(1_700_000_000 + i, 0, p) for i, p in enumerate(packets)], nh.LINKTYPES["ethernet"])
    fed: list[str] = []
    feed = ParamTracker.feed

    def counting(self: ParamTracker, f: Frame, fields: dict[str, object] | None = None) -> None:
        if f.msgdef is not None and f.msgdef.name == "PARAM_VALUE":
            fed.append("ok" if f.crc_status is CrcStatus.OK else "bad")
        feed(self, f, fields)

    with capture_file(data, ".tlog" if kind == "tlog" else ".pcap") as path:
        want = state(pure_analyses(path, PipelineOptions()))
        # the capture says something: changes signed and not, links, names as pymavlink decodes them (up to the
        # first NUL: A\0B is A)
        timeline = want["timeline"]
        assert isinstance(timeline, list)
        assert {e["signature"] for e in timeline} == {"no-key", "unsigned"}
        assert {e["name"] for e in timeline} >= {"RATE_RLL_P", "\\xffBAD\\xfe", "A", "SIXTEEN_CHARS_ID", "CUT"}
        assert any(e["kind"] == "set" and e["confirmed"] for e in timeline)
        monkeypatch.setattr(ParamTracker, "feed", counting)
        same_state(path)
        fed.clear()
        native_analyses(path, PipelineOptions())
        # the clean ones came from the payload rows; the two A\0B (bytes after param_id's NUL: a char-after-nul
        # note, so Python's) and the bad CRC were handed back
        assert fed == ["ok", "ok", "bad"]
