"""The native source feeds the findings' analyses in bulk (mavscope/export/native_findings.py): the state it
leaves them in must be the state the pure one-frame-at-a-time pass leaves, not only the findings (most
captures do not reach the limits and rare paths where a difference would show in a finding).

The pure side here is the reference written out: the session's frames, each given to `Analyses.add`. The
state compared: every sequence tracker (per sender and channel, and per link for replays) field by field,
the replay detector's remembered frames, the audit's first plaintexts and signing-stream targets, the
object and parameter trackers' activity clocks, the systems seen signing. `SeqTracker.skip` and
`Targets.add_run` are held to the calls they stand for, on hypothesis-drawn sequences.
"""

from __future__ import annotations

import dataclasses
import struct
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mavscope.analysis.expert import ReplayedCommands, SequenceAnomalies, UnsignedCommands
from mavscope.analysis.objects import ObjectTracker
from mavscope.analysis.objects.tracker import FTP_MESSAGE, TRACKED_MESSAGES
from mavscope.analysis.sequence import SeqTracker
from mavscope.capture.detect import open_capture
from mavscope.export import native, record_batches
from mavscope.export.native_columns import decoded, message_plan
from mavscope.export.options import ExportOptions, dialect_for
from mavscope.export.pure import Analyses
from mavscope.mavlink.dialect import Dialect, MessageDef
from mavscope.mavlink.frame import CrcStatus, Frame, Signature, new_frame
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
    return export.analyses


def _one(a: Analyses, kind: type) -> object:
    return next(d for d in a.expert.detectors if isinstance(d, kind))


def _tracker(tr: SeqTracker) -> dict[str, object]:
    state = dataclasses.asdict(tr)
    state["missing"] = list(tr.missing.items())  # insertion order matters (which slot is dropped first)
    return state


def state(a: Analyses) -> dict[str, object]:
    seq: SequenceAnomalies = _one(a, SequenceAnomalies)  # type: ignore[assignment]
    replay: ReplayedCommands = _one(a, ReplayedCommands)  # type: ignore[assignment]
    unsigned: UnsignedCommands = _one(a, UnsignedCommands)  # type: ignore[assignment]
    return {
        "counts": list(seq.counts.items()),
        "channels": [(s, [(ends, _tracker(tr)) for ends, tr in chans.items()])
                     for s, chans in seq.seqs.senders.items()],
        "extra": seq.seqs.extra,
        "events": [(k, ev.nums, ev.count) for k, ev in seq.events.items()],
        "links": [(k, _tracker(tr)) for k, tr in replay.trackers.items()],
        "seen": list(replay.seen.items()),
        "signing": sorted(unsigned.signing),
        "plain": sorted(a.audit.keystreams.plain.items()),
        "targets": list(a.audit.targets.seen.items()),
        "target_frames": [(s, [(f.record, f.index, f.raw) for f in fs]) for s, fs in a.audit.targets.frames.items()],
        "ticks": (a.objects.ctx.tick, a.params.objects.ctx.tick),
        "now": a.params.now,
    }


def same_state(path: str | Path, pipeline: PipelineOptions | None = None) -> None:
    pipeline = pipeline or PipelineOptions()
    want, got = state(pure_analyses(path, pipeline)), state(native_analyses(path, pipeline))
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


def _fed(seqs: list[int], raws: list[bytes | None]) -> SeqTracker:
    tr = SeqTracker()
    for i, (s, raw) in enumerate(zip(seqs, raws)):
        tr.feed(s, i, raw)
    return tr


@given(st.lists(st.integers(0, 255), min_size=1, max_size=60), st.integers(1, 400), st.booleans())
def test_skip_is_as_many_feeds_of_the_next_numbers(head: list[int], count: int, with_raw: bool) -> None:
    """After any history (gaps leave missing slots, repeats a restart run), `skip(k)` equals k feeds of
    last + 1, last + 2, ..., field for field."""
    raws = [bytes([s, i & 255]) if with_raw else None for i, s in enumerate(head)]
    fed = _fed(head, raws)
    assert fed.last is not None
    more = [(fed.last + k) % 256 for k in range(1, count + 1)]
    last_raw = b"last" if with_raw else None
    want = _fed(head + more, raws + [b"x"] * (count - 1) + [last_raw])
    got = _fed(head, raws)
    got.skip(count, last_raw)
    assert _tracker(got) == _tracker(want)


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
