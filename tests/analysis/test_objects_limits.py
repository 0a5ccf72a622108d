"""What a hostile capture can make the object reconstruction hold: bytes placed by offset match a naive
model (first copy kept), offsets far out, too many transfers, too many pieces and spent memory are cut and
said, and no vehicle path becomes a file name that leaves its directory."""

from __future__ import annotations

from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st

from mavscope.analysis.objects import Limits, analyse, file_name, is_plain_name, unsafe_reasons
from mavscope.analysis.objects.content import Budget, Content
from mavscope.mavlink.dialect import Dialect
from tests.support.ftpflows import BURST, EOF, OPEN_RO, READ, Flow, frames_of

pieces = st.lists(st.tuples(st.integers(0, 300), st.binary(min_size=1, max_size=40)), max_size=30)


@settings(max_examples=200, deadline=None)
@given(pieces)
def test_content_is_the_first_copy_of_every_byte(chunks: list[tuple[int, bytes]]) -> None:
    model: dict[int, int] = {}
    dup = conflict = 0
    content = Content(Budget(10_000, 10_000), 10_000, 1000)
    for offset, data in chunks:
        for i, b in enumerate(data):
            if offset + i in model:
                dup += model[offset + i] == b
                conflict += model[offset + i] != b
            else:
                model[offset + i] = b
        content.add(offset, data)
    size = max(model, default=-1) + 1
    assert content.data(size) == bytes(model.get(i, 0) for i in range(size))
    assert content.received == len(model)
    assert (content.duplicates, content.conflicts) == (dup, conflict)
    holes = [i for i in range(size) if i not in model]
    assert sum(b - a for a, b in content.gaps(size)) == len(holes)
    assert all(i not in model for a, b in content.gaps(size) for i in range(a, b))
    assert content.budget.zeros == len(holes)  # every hole charged, every filled one given back


def read_reply(flow: Flow, session: int, offset: int, data: bytes, announce: int | None = None) -> None:
    """An open of /s<session> (announcing `announce` bytes, if given) and one read answered at `offset`."""
    req = flow.request(OPEN_RO, data=f"/s{session}".encode())
    flow.reply(req, session=session, data=b"" if announce is None else announce.to_bytes(4, "little"))
    r = flow.request(READ, session=session, size=len(data), offset=offset)
    flow.reply(r, data=data)


def test_holes_are_paid_for_from_one_allowance(tmp_path: Path, dialect: Dialect) -> None:
    """A piece far from the start of its object stood for its whole hole of zeros in memory, in the hash
    and on disk: 20 frames of 10 bytes at offset 500,000 made 10 MB of files. With 64 KiB of holes allowed
    for all objects, the first two pieces pay for their holes (2 x 30,000 bytes), the others are not kept
    and are counted (by hand: 20 objects, 18 x 10 bytes dropped)."""
    flow = Flow()
    for session in range(20):
        read_reply(flow, session, 30_000 if session < 2 else 500_000, b"z" * 10)
    log = analyse(frames_of(flow.write(tmp_path), dialect), dialect, Limits(max_object=1 << 20, max_holes=65_536))
    assert [o.size for o in log.objects] == [30_010, 30_010] + [0] * 18
    assert [o.dropped_bytes for o in log.objects] == [0, 0] + [10] * 18
    assert sum(len(o.data) for o in log.objects) == 60_020
    assert any("bytes of holes" in k for k in log.given_up)
    assert all(any("bytes of holes" in p for p in o.problems) for o in log.objects[2:])

    # a hole filled by data later is given back: two files of 100 bytes sent back to front in pieces of 10
    # each make a hole of 90 bytes first, so both fit an allowance of 100
    flow = Flow()
    for session in range(2):
        req = flow.request(OPEN_RO, data=f"/r{session}".encode())
        flow.reply(req, session=session, data=(100).to_bytes(4, "little"))
        for offset in range(90, -1, -10):
            r = flow.request(READ, session=session, size=10, offset=offset)
            flow.reply(r, data=bytes([offset]) * 10)
    log = analyse(frames_of(flow.write(tmp_path), dialect), dialect, Limits(max_holes=100))
    assert [(o.size, o.complete, o.dropped_bytes) for o in log.objects] == [(100, True, 0), (100, True, 0)]
    assert log.objects[1].data == b"".join(bytes([k]) * 10 for k in range(0, 100, 10))

    # the zeros after the last byte received, up to the size the server announced, are holes too
    flow = Flow()
    read_reply(flow, 0, 0, b"abc", announce=1 << 19)
    log = analyse(frames_of(flow.write(tmp_path), dialect), dialect, Limits(max_holes=65_536))
    [obj] = log.objects
    assert (obj.size, obj.data, obj.complete) == (3, b"abc", False)
    assert any("holes was reached: only its first 3 bytes were kept" in p for p in obj.problems)


def test_an_offset_far_out_is_cut_at_the_object_limit(tmp_path: Path, dialect: Dialect) -> None:
    flow = Flow()
    req = flow.request(OPEN_RO, data=b"/big")
    flow.reply(req, session=0, data=(0xFFFF_FFFF).to_bytes(4, "little"))  # announces 4 GiB
    r = flow.request(READ, size=10, offset=0xFFFF_FF00)
    flow.reply(r, data=b"x" * 10)
    flow.nak(flow.request(READ, size=10, offset=0xFFFF_FFF0), EOF)
    log = analyse(frames_of(flow.write(tmp_path), dialect), dialect, Limits(max_object=4096))
    [obj] = log.objects
    assert obj.size == 4096 and len(obj.data) == 4096 and not obj.complete
    assert obj.dropped_bytes == 10
    assert [f.code for f in log.findings] == ["object-limit"]


def test_the_memory_budget_and_the_number_of_pieces(tmp_path: Path, dialect: Dialect) -> None:
    flow = Flow()
    for session in range(3):
        req = flow.request(OPEN_RO, data=f"/f{session}".encode())
        flow.reply(req, session=session, data=(300).to_bytes(4, "little"))
        for offset in range(0, 300, 100):
            r = flow.request(READ, session=session, size=100, offset=offset)
            flow.reply(r, data=bytes([session]) * 100)
    log = analyse(frames_of(flow.write(tmp_path), dialect), dialect, Limits(max_total=500))
    # 500 bytes: the first file whole (300), the second up to the budget (200), nothing of the third
    assert [len(o.data) for o in log.objects] == [300, 200, 0]
    assert any("memory limit" in k for k in log.given_up)

    flow = Flow()
    req = flow.request(OPEN_RO, data=b"/frag")
    flow.reply(req, session=0, data=(1000).to_bytes(4, "little"))
    burst = flow.request(BURST, size=1)
    for k in range(20):  # one byte in two: 20 separate pieces
        flow.reply(burst, data=b"y", offset=2 * k, seq=burst.seq + 1 + k)
    log = analyse(frames_of(flow.write(tmp_path), dialect), dialect, Limits(max_ranges=5))
    [obj] = log.objects
    assert obj.received == 5 and obj.dropped_bytes == 15


def test_too_many_transfers_at_once_close_the_oldest(tmp_path: Path, dialect: Dialect) -> None:
    flow = Flow()
    for session in range(6):
        req = flow.request(OPEN_RO, data=f"/f{session}".encode())
        flow.reply(req, session=session, data=(4).to_bytes(4, "little"))
    log = analyse(frames_of(flow.write(tmp_path), dialect), dialect, Limits(max_open=4))
    assert len(log.objects) == 6  # closed early, not dropped
    assert sum(1 for o in log.objects if any("closed early" in p for p in o.problems)) == 2
    log = analyse(frames_of(flow.write(tmp_path), dialect), dialect, Limits(max_objects=2))
    assert len(log.objects) == 2 and any("counted, not kept" in k for k in log.given_up)


@given(st.text(max_size=400))
def test_every_vehicle_path_becomes_one_plain_file_name(path: str) -> None:
    name = file_name(7, path, ".bin")
    assert is_plain_name(name) and "/" not in name and "\\" not in name and "\0" not in name
    assert name.startswith("0007-") and len(name) <= 120


def test_unsafe_paths_are_recognised() -> None:
    assert unsafe_reasons("/APM/scripts/a.lua") == []
    assert unsafe_reasons("@PARAM/param.pck?withdefaults=1") == []
    assert unsafe_reasons("../../etc/shadow") == ["a '..' component"]
    assert unsafe_reasons("a\x00b") == ["a NUL byte"]
    assert unsafe_reasons("a\x1bb") == ["control characters"]
    assert unsafe_reasons("C:\\x") == ["a backslash (or bytes that are not UTF-8, shown escaped)"]
    assert unsafe_reasons("x" * 300) == ["more than 255 bytes"]
    assert file_name(1, "../../etc/shadow") == "0001-etc_shadow"
