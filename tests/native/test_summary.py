"""The native engine and the pure-Python path print the same summary lines (`mavscope read FILE`, `-c N`).

The pure path (MAVSCOPE_PURE=1: output/text.py summary_line per frame) is the reference. Through the
command line on every bundled capture (no keys, the key of signed_udp.pcap, --use-leaked-keys) and every
real capture beside the repository; through the API on hypothesis-generated captures (the strategies of
test_generated.py: every link layer, pcap/pcapng/tlog/raw, damaged and signed frames, random payloads of
random messages, so random enum values, degE7 coordinates, strings, floats) and arbitrary bytes, with a
64-byte read window too, and with -c counts that end inside a record. Stdout, stderr and the exit status
must be equal.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tests.conftest import CAPTURES, Cli
from tests.native import build as nh
from tests.native.engines import KEY_OPTIONS as CLI_KEYS
from tests.native.engines import capture_file, native_summary_output, pure_output, same, summary_render
from tests.native.test_generated import CLI_KEY_CHOICES, DAMAGED_FILES, DIALECT, FEWER, FEWEST, SETTINGS, capture, frame
from tests.native.test_identity import KEY_OPTIONS, real_names

pytest.importorskip("mavscope._native", reason="the native extension is not built (no compiler at install)")

BUNDLED = sorted(p.name for p in CAPTURES.iterdir() if p.suffix not in (".md", ".json"))
SUMMARY: tuple[str, ...] = ()  # the output options of the summary lines: none


@pytest.mark.parametrize("keys", sorted(KEY_OPTIONS))
@pytest.mark.parametrize("name", BUNDLED)
def test_bundled_capture(name: str, keys: str, cli: Cli) -> None:
    same(cli, CAPTURES / name, *KEY_OPTIONS[keys], fmt=SUMMARY)


@pytest.mark.parametrize("count", ["1", "2", "7", "100"])
@pytest.mark.parametrize("name", ["px4_sitl_udp.pcap", "signed_udp.pcap", "damaged.pcap", "px4_sitl.tlog",
                                  "commands_ack.pcap", "serial_dump.raw"])
def test_count(name: str, count: str, cli: Cli) -> None:
    """-c N stops after N frames on both paths (px4_sitl_udp.pcap has records of two frames: -c 7 ends
    inside one)."""
    result = same(cli, CAPTURES / name, "-c", count, fmt=SUMMARY)
    assert result.out.count("\n") <= int(count)


@pytest.mark.parametrize("name", real_names() or ["(absent)"])
def test_real_capture(name: str, real_captures: Path, cli: Cli) -> None:
    same(cli, real_captures / name, fmt=SUMMARY)
    same(cli, real_captures / name, "-c", "1000", fmt=SUMMARY)


def test_most_frames_are_written_natively(dialect: object) -> None:
    """The native writer does the work: on px4_sitl_udp.pcap (clean UDP, HEARTBEAT, ATTITUDE, positions,
    COMMAND_LONG, STATUSTEXT of id 0 among them) every frame is written in C: the two records handed back
    hold no frame."""
    out, _, stats = native_summary_output(CAPTURES / "px4_sitl_udp.pcap", dialect)  # type: ignore[arg-type]
    # pymavlink's counts (captures/expected.json frame_list): 1371 frames, 5 STATUSTEXT (msgid 253)
    expected = json.loads((CAPTURES / "expected.json").read_text())["px4_sitl_udp.pcap"]
    assert len([f for f in expected["frame_list"] if f[5] == 253]) == 5 and out.count(b"\n") == 1371
    assert stats["frames_native"] == 1371
    assert stats["records_handed_back"] == 2


def test_a_chunk_of_a_long_statustext_is_pythons(dialect: object, cli: Cli) -> None:
    """STATUSTEXT's Info says which chunk of a long text a frame is ("[chunk 1 of id 7]", fields/summary.py)
    where its `id` is not 0: those frames are handed back, the others written in C; both engines print the
    same lines (built with pymavlink: id 0, id 7 chunk 0 and 1, a v1 STATUSTEXT, which has no id)."""
    from tests.support.builders import mav1, mav2, tlog_spaced

    v, old = mav2(1, 1), mav1(1, 1)
    frames = [bytes(v.statustext_encode(6, b"plain", 0, 0).pack(v)),
              bytes(v.statustext_encode(6, b"first part", 7, 0).pack(v)),
              bytes(v.statustext_encode(6, b"second part", 7, 1).pack(v)),
              bytes(old.statustext_encode(4, b"v1 text").pack(old))]
    with capture_file(tlog_spaced(frames)) as path:
        out, _, stats = native_summary_output(path, dialect)  # type: ignore[arg-type]
        assert stats["frames_native"] == 2 and stats["records_handed_back"] == 2  # the two chunks of id 7
        lines = out.decode().splitlines()
        assert lines[1].endswith("[chunk 0 of id 7]") and lines[2].endswith("[chunk 1 of id 7]")
        assert "chunk" not in lines[0] and "chunk" not in lines[3]
        same(cli, path, fmt=SUMMARY)


def check(data: bytes, keys: str, count: int | None = None) -> None:
    """Both engines on `data` through the API (and with a 64-byte read window): equal stdout and stderr."""
    with capture_file(data) as path:
        expected = pure_output(path, DIALECT, keys, render=summary_render(path, DIALECT), count=count)
        for window in (None, 64):
            assert native_summary_output(path, DIALECT, keys, window=window, count=count)[:2] == expected


@SETTINGS
@given(capture(), st.sampled_from(["none", "none", "key", "leaked"]))
def test_generated_capture_is_identical(data: bytes, keys: str) -> None:
    check(data, keys)


@FEWER
@given(capture(), st.integers(1, 12))
def test_generated_capture_with_a_count(data: bytes, count: int) -> None:
    check(data, "none", count)


@FEWER
@given(*DAMAGED_FILES)
def test_arbitrary_bytes_are_identical(tail: bytes, head: bytes) -> None:
    check(head + tail, "none")


@FEWEST
@given(capture(), CLI_KEY_CHOICES)
def test_generated_capture_through_the_command_line(data: bytes, keys: str) -> None:
    """The whole command: key options, problems on stderr, the no-frames line, exit status."""
    with capture_file(data) as path:
        same(Cli(), path, *CLI_KEYS[keys], fmt=SUMMARY)


@FEWER
@given(st.lists(st.one_of(frame(), st.binary(min_size=1, max_size=12).filter(lambda b: b[0] not in (0xFD, 0xFE))),
                min_size=1, max_size=12))
def test_tlog_with_text_runs(entries: list[bytes]) -> None:
    """A tlog whose entries mix frames and console text (a run of text entries is joined by the Python
    dissector and ends before the next record walked natively)."""
    t0 = 1_700_000_000_000_000
    check(nh.tlog([(t0 + i * 1000, e) for i, e in enumerate(entries)]), "none")


def test_pcapng_times_out_of_range() -> None:
    """pcapng times C does not compute (tsresol 10^-20: units above 2^64) or does not format (a span of
    more than 10^15 s from the first record): those records are written by Python, the rest natively."""
    md = DIALECT.messages[0]
    hb = nh.frame_v2(md, 0, bytes(md.length), 1, 1, 1)
    pkt = nh.link("ethernet", nh.ipv4(bytes([10, 0, 0, 1]), bytes([10, 0, 0, 2]), 17, nh.udp(14550, 14550, hb)),
                  False)
    for tsresol in (20, 19, 0x80 | 63, 0):
        for ticks in (0, 1, 2**63, 2**64 - 1, 1_700_000_000 * 10**6):
            data = nh.pcapng([(1, tsresol, 0), (1, 6, 0)], [(1, 1_700_000_000 * 10**6, pkt), (0, ticks, pkt),
                                                            (1, 1_700_000_000 * 10**6 + 5, pkt)])
            check(data, "none")


def test_command_params_are_named_as_python_names_them() -> None:
    """COMMAND_LONG, COMMAND_INT, MISSION_ITEM(_INT) for every MAV_CMD of the dialect, param1 whole (enum
    entries, message ids, bits of a bitmask, values no entry has), negative, fractional, NaN or infinite
    (the pure path raised OverflowError on an infinite one: int(inf); now neither names it)."""
    import struct as s

    pkts = []
    commands = sorted(DIALECT.enums["MAV_CMD"].entries)
    for name in ("COMMAND_LONG", "COMMAND_INT", "MISSION_ITEM", "MISSION_ITEM_INT"):
        md = DIALECT.messages[next(i for i, m in DIALECT.messages.items() if m.name == name)]
        offsets = {f.name: f.offset for f in md.fields}
        for k, command in enumerate(commands):
            for v in (0.0, -0.0, 1.0, 2.0, 3.0, 5.0, 7.0, 148.0, -1.0, 0.5, math.nan, 1e30, 2.0**40, math.inf,
                      -math.inf):
                body = bytearray(md.length)
                body[offsets["command"]:offsets["command"] + 2] = s.pack("<H", command)
                body[offsets["param1"]:offsets["param1"] + 4] = s.pack("<f", v)
                pkts.append(nh.frame_v2(md, md.id, bytes(body), k & 0xFF, 255, 190))
    udp = [nh.link("ethernet", nh.ipv4(bytes([10, 0, 0, 1]), bytes([10, 0, 0, 2]), 17, nh.udp(14550, 14550, f)),
                   False) for f in pkts]
    check(nh.pcap([(1_700_000_000 + i, 0, p) for i, p in enumerate(udp)], 1), "none")


def test_the_native_summary_serves_only_a_utf8_stream_that_is_not_a_terminal(monkeypatch: pytest.MonkeyPatch) -> None:
    """A terminal, or a stream that does not take UTF-8, gets the pure path (its lines are text); -V and -x
    too. Told apart by a native writer that fails."""
    import io

    import mavscope.native.summary
    from mavscope.cli import Env, main

    class Used(Exception):
        pass

    def fail(*args: object, **kwargs: object) -> dict[str, int]:
        raise Used

    monkeypatch.setattr(mavscope.native.summary, "write_summary", fail)

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    path = str(CAPTURES / "px4_sitl_udp.pcap")
    utf16 = io.TextIOWrapper(io.BytesIO(), encoding="utf-16")
    for stdout, argv in ((Terminal(), []), (utf16, []), (io.StringIO(), ["-V"]), (io.StringIO(), ["-x"])):
        assert main(["read", path, *argv], Env(stdout=stdout, stderr=io.StringIO(), environ={})) == 0
    utf8 = io.TextIOWrapper(io.BytesIO(), encoding="utf-8")
    for stdout in (io.StringIO(), utf8):
        with pytest.raises(Used):
            main(["read", path], Env(stdout=stdout, stderr=io.StringIO(), environ={}))
