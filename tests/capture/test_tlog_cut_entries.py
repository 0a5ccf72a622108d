"""Tlog entries cut short with a whole entry starting inside them (mavscope.capture.tlog.cut_at, and its C twin).

A logger that lost bytes leaves an entry whose frame is shorter than its LEN says; the next entry starts inside
what that LEN claims. The expected answers come from MAVLink's own C parser (tests/support/cparser.py, from
pymavlink's mavlink_helpers.h) fed the whole file byte by byte, timestamps included, with one parser
(`keep=True` over pieces of the file: one run of bytes), through both entry points (mavlink_parse_char and
mavlink_frame_char_buffer): every frame it reads must be one mavscope shows with a good CRC, at the same file
offset. By hand: (a) an entry cut to its STX makes the next entry's timestamp bytes the frame's LEN and
INCOMPAT_FLAGS (0x06 for a 2026 timestamp: a flag the parser does not know), so the parser drops it there and
reads the next entry's frame; (b) an entry cut 9 bytes short ends, by its LEN, on the next entry's STX: the bad
CRC's last byte is 0xFD, and mavlink_parse_char starts a frame there and reads the next entry. Before the fix
mavscope read the cut entry on over the next one and skipped that as a "broken tlog entry".
"""

from __future__ import annotations

import random
from pathlib import Path

import pytest

from mavscope.capture.detect import open_capture
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus
from mavscope.pipeline.dissect import Anomaly, Dissector
from tests.support.cparser import CParser, require_c_parser
from tests.support.flows import T0, Sender, command_long, heartbeat, tlog

PURE, NATIVE = {"MAVSCOPE_PURE": "1"}, {"MAVSCOPE_PURE": ""}


@pytest.fixture(scope="module")
def cparser() -> CParser:
    return require_c_parser()


def c_reads(cparser: CParser, data: bytes, entry: str | None = None) -> set[tuple[int, int]]:
    """(file offset, size) of every frame the C parser reads from the file's bytes, one parser throughout."""
    step = 1 << 16
    pieces = [data[i:i + step] for i in range(0, len(data), step)]
    return {(k * step + s, n) for k, found in enumerate(cparser.frames(pieces, entry, keep=True)) for s, n in found}


def shown(cli, path: Path, dialect: Dialect) -> set[tuple[int, int]]:  # type: ignore[no-untyped-def]
    """(file offset, size) of each frame mavscope shows with a good CRC; both engines' `read` must agree."""
    assert cli.jsonl(path, environ=NATIVE) == cli.jsonl(path, environ=PURE)
    with open_capture(path) as r:
        return {(f.offset, len(f.raw)) for f in Dissector(dialect).run(r)
                if type(f) is not Anomaly and f.crc_status is CrcStatus.OK}


def flow() -> list[bytes]:
    v, g = Sender(1, 1), Sender(255, 190)
    out = []
    for i in range(12):
        out.append(v.pack(heartbeat()))
        out.append(g.pack(command_long(400, 1.0)) if i % 3 == 0 else g.pack(heartbeat(gcs=True)))
    return out


def test_what_the_c_parser_reads_past_a_cut_entry_is_shown(cli, tmp_path: Path, cparser: CParser,
                                                          dialect: Dialect) -> None:  # type: ignore[no-untyped-def]
    frames = flow()
    arm = frames[1]  # a COMMAND_LONG ARM, entry 2
    cases = {
        "cut to its first byte": [frames[0], arm[:1], arm, *frames[2:]],
        "cut to end on the next STX": [frames[0], frames[3][:-9], arm, *frames[2:]],
    }
    rng = random.Random(35)
    for k in range(6):  # entries cut at random places, one to four of them
        fs = list(frames)
        for i in rng.sample(range(1, len(fs) - 1), rng.randint(1, 4)):
            fs[i] = fs[i][:rng.randint(1, len(fs[i]) - 1)]
        cases[f"random {k}"] = fs
    for name, fs in cases.items():
        data = tlog([(T0 + i * 0.1, f) for i, f in enumerate(fs)])
        path = tmp_path / f"{name}.tlog"
        path.write_bytes(data)
        reads = c_reads(cparser, data)
        got = shown(cli, path, dialect)
        assert reads <= got, (name, sorted(reads - got))
        if not name.startswith("random"):
            at = data.index(arm, 8 + len(fs[0]) + 8 + len(fs[1]))  # the ARM's entry, after the cut one
            assert (at, len(arm)) in reads  # the parser reads it (by hand, above) ...
            assert (at, len(arm)) in got  # ... and mavscope shows it
        with open_capture(path) as r:  # the reader says where it cut an entry short
            cut = [n.message for rec in r for n in rec.notes if n.code == "record-truncated"]
        assert all("starts inside it" in m for m in cut) and len(cut) >= (0 if name.startswith("random") else 1)


def test_real_tlogs_both_engines_and_what_the_c_parser_reads(cli, real_captures: Path, cparser: CParser,
                                                            dialect: Dialect) -> None:  # type: ignore[no-untyped-def]
    """On the real tlogs (the ArduSub one has five components), every frame the C parser reads from the file
    byte by byte is shown with a good CRC, and the engines agree."""
    for name in ("ardusub_log_tools_small.tlog", "px4_2018_params_offboard.tlog"):
        path = real_captures / name
        reads = c_reads(cparser, path.read_bytes())
        got = shown(cli, path, dialect)
        assert reads <= got, (name, sorted(reads - got)[:10])


def test_the_fast_path_reads_each_timestamp_once(tmp_path: Path) -> None:
    """The reader's tight loop tests that an entry starts where each one ends (the cut-entry rule above) by
    reading the next entry's timestamp, which is then that entry's own: one struct unpack an entry, no Python
    call besides the record's. Counted with a profiler (the work, not the time: tests/support/cost.py's rule)."""
    import sys

    from mavscope.capture.tlog import TlogReader

    s = Sender(1, 1)
    n = 2000
    path = tmp_path / "clean.tlog"
    path.write_bytes(tlog([(T0 + i * 0.01, s.pack(heartbeat())) for i in range(n)]))
    calls: dict[str, int] = {}

    def prof(frame, event, arg):  # type: ignore[no-untyped-def]
        if event == "c_call":
            calls[arg.__name__] = calls.get(arg.__name__, 0) + 1
        elif event == "call":
            calls[frame.f_code.co_name] = calls.get(frame.f_code.co_name, 0) + 1

    reader = TlogReader(str(path))
    sys.setprofile(prof)
    try:
        records = list(reader)
    finally:
        sys.setprofile(None)
    assert len(records) == n and all(r.time == pytest.approx(T0 + i * 0.01) for i, r in enumerate(records))
    # the entries past the first window's lookahead are the tight loop's; allow the window edges a few more
    assert calls.get("unpack_from", 0) <= n + 64, calls
    assert calls.get("near", 0) <= 16, calls
