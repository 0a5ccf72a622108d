"""The TUI's model (mavscope.index, no Textual) and the app on a large generated capture."""

from __future__ import annotations

from pathlib import Path

import pytest

from mavscope.browse.index import FrameIndex
from mavscope.capture.detect import open_capture
from mavscope.commands.tui import parse_options
from mavscope.mavlink.frame import SignatureStatus
from mavscope.pipeline.dissect import Anomaly, Dissector
from mavscope.pipeline.session import build_pipeline
from mavscope.tui.app import create_app
from tests.conftest import ROOT
from tests.support.tui import CAPTURES, SIZE, run, wait_for, write_big_capture

ALL = sorted(p for p in CAPTURES.iterdir() if p.suffix in (".pcap", ".pcapng", ".tlog", ".raw"))


def _pipeline(path: Path, dialect, args: list[str] = ()):  # type: ignore[no-untyped-def]
    reader = open_capture(path)
    options = parse_options([str(path), *args]).pipeline
    return reader, build_pipeline(options, dialect, reader)


@pytest.mark.parametrize("path", ALL, ids=lambda p: p.name)
def test_frames_rebuilt_from_the_index_equal_the_pipelines(path: Path, dialect) -> None:  # type: ignore[no-untyped-def]
    reader, items = _pipeline(path, dialect)
    with reader:
        expected = [f for f in items if type(f) is not Anomaly]
    reader, items = _pipeline(path, dialect)
    index = FrameIndex(dialect, path)
    with reader:
        progress = index.build(items, position=lambda: reader.position, total=reader.size)
    assert progress.done and progress.frames == len(expected) == len(index)
    assert [index.frame(i) for i in range(len(index))] == expected
    assert list(index.frames()) == expected
    for i in (0, len(index) // 2, len(index) - 1):
        row = index.row(i)
        f = expected[i]
        assert (row.record, row.index, row.sysid, row.compid, row.seq, row.msgid, row.crc_status) == \
            (f.record, f.index, f.sysid, f.compid, f.seq, f.msgid, f.crc_status)
        assert index.detail(i).frame == f
    index.close()


def test_security_verdicts_survive_the_index(dialect) -> None:  # type: ignore[no-untyped-def]
    path = CAPTURES / "signed_udp.pcap"
    reader, items = _pipeline(path, dialect, ["--key", "passphrase:mavscope-demo"])
    index = FrameIndex(dialect, path)
    with reader:
        index.build(items)
    assert {index.row(i).signature_status.value for i in range(len(index))} == {"valid"}
    assert index.frame(0).security.key == "key1"
    assert len(index._securities) <= 4  # interned, not one per frame


def test_a_bounded_index_drops_rows_without_renumbering_the_rest(dialect) -> None:  # type: ignore[no-untyped-def]
    """A live index keeps its newest rows; a row number taken before a drop still names the same frame
    (or raises IndexError once that frame is gone), never a newer one."""
    path = CAPTURES / "px4_sitl_udp.pcap"
    reader, items = _pipeline(path, dialect)
    with reader:
        expected = [f for f in items if type(f) is not Anomaly]
    index = FrameIndex(dialect)
    index.limit = 100
    for f in expected[:100]:
        index.add(f)
    index.detail(90)
    for f in expected[100:300]:
        index.add(f)
    assert len(index) <= 100 and index.end == 300 and index.first == 300 - len(index)
    assert list(index.rows()) == list(range(index.first, 300))
    with pytest.raises(IndexError):
        index.row(90)
    with pytest.raises(IndexError):
        index.frame(index.first - 1)
    with pytest.raises(IndexError):
        index.detail(90)  # not served from the detail cache either
    for n in (index.first, 250, 299):
        assert index.frame(n) == expected[n]
        assert index.row(n).row == n
    assert index.find_record(expected[250].record) == 250
    assert index.find_record(expected[10].record) is None
    assert list(index.frames(range(0, 300))) == expected[index.first:300]  # dropped rows skipped
    assert index.column("seq", [5, 250, 299]) == [None, expected[250].seq, expected[299].seq]


def test_reassembled_tcp_frames_keep_their_bytes_and_offsets(dialect) -> None:  # type: ignore[no-untyped-def]
    path = CAPTURES / "px4_sitl_tcp.pcap"
    reader, items = _pipeline(path, dialect)
    with reader:
        expected = [f for f in items if type(f) is not Anomaly]
    reader, items = _pipeline(path, dialect)
    index = FrameIndex(dialect, path)
    with reader:
        index.build(items)
    split = [i for i, f in enumerate(expected) if f.span]
    assert split, "the capture has frames split across segments"
    assert all(index.frame(i) == expected[i] for i in split)


def test_build_reports_progress_and_stops_when_cancelled(dialect) -> None:  # type: ignore[no-untyped-def]
    path = CAPTURES / "px4_sitl_udp.pcap"
    seen = []
    index = FrameIndex(dialect, path)
    with open_capture(path) as reader:
        p = index.build(Dissector(dialect).run(reader), on_progress=seen.append, cancelled=lambda: len(seen) >= 3,
                        every=100)
    assert p.cancelled and not p.done
    assert 0 < len(index) < 1371
    assert [s.frames for s in seen] == sorted(s.frames for s in seen)
    assert [f.record for f in index.frames()] == [index.row(n).record for n in range(len(index))]  # rows stay valid


@pytest.mark.parametrize("engine", ["pure", "native"])
def test_large_capture_first_rows_before_the_index_completes(tmp_path: Path, dialect, engine: str,  # type: ignore[no-untyped-def]
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    """200k records (about 220k frames): the first screen is drawn before indexing ends, and the list is
    usable meanwhile. The index build is held at a gate after its first 5,000 frames (native: after its
    first chunk), so the test does not depend on how fast this machine indexes (it once failed 4 runs in
    7 by assuming it)."""
    import threading

    from mavscope.native import core
    from mavscope.native import index as native

    if engine == "native" and not (core.available({}) and native.indexes("pcap")):
        pytest.skip("the native engine is not built")
    monkeypatch.setenv("MAVSCOPE_PURE", "1" if engine == "pure" else "")
    path = tmp_path / "big.pcap"
    write_big_capture(path, 200_000)
    gate = threading.Event()

    async def scenario() -> None:
        app = create_app(path)
        opened = app.source.open

        def gated_open():  # type: ignore[no-untyped-def]
            reader, items, t0 = opened()

            def held():  # type: ignore[no-untyped-def]
                for n, item in enumerate(items):
                    if n == 5000:
                        gate.wait(120)
                    yield item
            return reader, held(), t0

        app.source.open = gated_open  # type: ignore[method-assign]
        extend = FrameIndex.extend
        chunks = []

        def gated_extend(self, *args):  # type: ignore[no-untyped-def]
            if chunks:
                gate.wait(120)
            chunks.append(len(self))
            extend(self, *args)

        monkeypatch.setattr(FrameIndex, "extend", gated_extend)
        async with app.run_test(size=SIZE) as pilot:
            await wait_for(pilot, lambda: app.packet_list.count > 0 and app.tree.detail is not None, timeout=60)
            assert app.first_rows_at is not None
            assert not app.index.done, "the index was complete before the first rows were shown"
            lines = app.packet_list.visible_rows()
            assert lines[:3] == [0, 1, 2]
            assert "indexing" in str(app.status.render())
            # the list stays usable while indexing: moving and scrolling work
            await pilot.press("pagedown", "down")
            assert app.packet_list.cursor == app.packet_list.page + 1
            gate.set()
            await wait_for(pilot, lambda: app.index.done, timeout=300)
            assert len(app.index) > 200_000
            assert app.packet_list.count == len(app.index)
            await pilot.press("end")
            await pilot.pause()
            assert app.tree.detail.frame.record == 200_000
            assert app.index.memory() < 100 * len(app.index)  # bytes per frame, far below a Frame's
            assert bool(chunks) == (engine == "native")  # the build the test meant ran

    try:
        run(scenario())
    finally:
        gate.set()


def test_rejudge_replaces_verdicts_and_the_stages_notes_without_doubling_them(dialect) -> None:  # type: ignore[no-untyped-def]
    """What a key added during live capture does to the rows held: verdicts from the new stage; the
    notes the old stage added are replaced (an injected unsigned frame keeps exactly one note)."""
    from mavscope.capture.base import LINKTYPE_MAVLINK_TLOG, Record
    from mavscope.security.keys import build_material
    from mavscope.security.stage import NOTE_CODES, SecurityStage
    from tests.support.security import PASSPHRASE, SHA_KEY, command_long, heartbeat, signer

    raws = [heartbeat(signer(SHA_KEY)), command_long(signer(None))]
    raws.append(raws[0])  # sent again
    records = [Record(n, 1_773_482_400.0 + n, LINKTYPE_MAVLINK_TLOG, raw, 8, len(raw)) for n, raw in enumerate(raws, 1)]
    index = FrameIndex(dialect)
    index.build(SecurityStage().run(Dissector(dialect).run(records)))
    before = [(index.row(n).signature_status, [x.code for x in index.frame(n).notes]) for n in index.rows()]
    assert before[0][0] is before[2][0] is SignatureStatus.NO_KEY
    assert before[1] == (None, ["unsigned-in-signed-stream"])  # key-free: the sender signed before
    index.detail(2)  # cached with the old verdict
    stage = SecurityStage(build_material([f"passphrase:{PASSPHRASE}"]))
    assert index.rejudge(stage.run, NOTE_CODES) == 3
    after = [(index.row(n).signature_status, [x.code for x in index.frame(n).notes]) for n in index.rows()]
    assert after == [(SignatureStatus.VALID, []), (None, ["unsigned-in-signed-stream"]),
                     (SignatureStatus.REPLAY, [])]
    assert index.detail(2).frame.security.signature_status is SignatureStatus.REPLAY  # not the cached one


def test_note_codes_lists_every_note_the_security_layer_adds() -> None:
    """FrameIndex.rejudge strips exactly these before judging a frame again."""
    import re

    from mavscope.security.stage import NOTE_CODES

    root = ROOT / "mavscope" / "security"
    codes = {m for p in root.glob("*.py") for m in re.findall(r'\bnote\(\s*"([a-z0-9-]+)"', p.read_text())}
    assert codes == NOTE_CODES
