"""Raw byte streams on the native engine: C writes the clean stretches, Python's framer the damaged pieces.

The reference is the pure path (Dissector._stream: one StreamFramer over the reader's 64 KiB chunks, frames
numbered 1..N across the stream). The native walker (walk.c walk_raw, docs/native.md "What C writes and what
it hands back") writes the frames of a stretch while that framer is idle and hands back a piece from where
damage begins to a cut where the framer is idle again. Both engines must print the same bytes (stdout,
stderr; through the command line the exit status too) in `read -T jsonl`, `read` (summary lines) and
`stats --json`, on the bundled and the real raw captures, on streams built by hand (each says what the framer
shows there, worked out from framing.py's rules by hand) and on generated streams; and the walker must take
the clean stretches itself (its counters), so that it cannot silently hand everything back.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mavscope.mavlink.dialect import load_dialect
from mavscope.mavlink.frame import Frame
from mavscope.pipeline.dissect import Anomaly
from tests.conftest import CAPTURES, Cli
from tests.native import build as nh
from tests.native.engines import (
    PURE,
    capture_file,
    native_output,
    native_summary_output,
    pure_output,
    summary_render,
)

pytest.importorskip("mavscope._native", reason="the native extension is not built (no compiler at install)")

DIALECT = load_dialect()
M = DIALECT.messages
CHUNK = 65536  # capture/raw.py CHUNK: the reader's chunks, on both engines
REAL_RAW = ("ap_hw_copter_cubeorange_raw_serial_corrupt_adsb_v1.raw", "gomavlib_signed_testvectors_key4F_DERIVED.raw",
            "px4_fw_mission_download_raw.bin")  # (serial_dump.raw is a bundled capture: BUNDLED's tests)
KEY4F = "hex:" + "4f" * 32  # the gomavlib test vectors' key (PROVENANCE.md)


def v2(msgid: int, payload: bytes | None = None, seq: int = 0, sysid: int = 1, compid: int = 1, **kw: object) -> bytes:
    md = M.get(msgid)
    if payload is None:
        payload = bytes(range(7, 7 + (md.length if md is not None else 9)))
    return nh.frame_v2(md, msgid, payload, seq & 0xFF, sysid, compid, **kw)  # type: ignore[arg-type]


def v1(msgid: int, seq: int = 0, sysid: int = 1, compid: int = 1) -> bytes:
    md = M[msgid]
    return nh.frame_v1(md, bytes(range(3, 3 + md.base_length)), seq & 0xFF, sysid, compid)


def bad_crc(frame: bytes) -> bytes:
    b = bytearray(frame)
    b[10 + b[1]] ^= 0x5A  # the CRC's low byte (v2)
    return bytes(b)


def clean(n: int, start: int = 0, msgid: int = 30) -> bytes:
    return b"".join(v2(msgid, seq=start + i) for i in range(n))


def filler(size: int) -> list[bytes]:
    """Clean ATTITUDE frames (trimmed payloads) of exactly `size` bytes in all (size >= 26)."""
    out, seq = [], 0
    while size > 80:
        out.append(v2(30, bytes(range(1, 29)), seq))
        size -= 40
        seq += 1
    a = size // 2
    for part in (a, size - a):  # each 20..40 bytes: a payload of 8..28 bytes
        out.append(v2(30, bytes(range(1, part - 12 + 1)), seq))
        seq += 1
    return out


def both(data: bytes, keys: str = "none") -> tuple[list[dict], str, dict[str, int]]:
    """`read -T jsonl` and the summary lines of the raw stream `data` on both engines (through the API):
    identical; the JSON rows, stderr and the native walk's counters."""
    with capture_file(data, ".raw") as path:
        p_out, p_err = pure_output(path, DIALECT, keys)
        n_out, n_err, stats = native_output(path, DIALECT, keys)
        assert n_err == p_err
        assert n_out == p_out
        render = summary_render(path, DIALECT)
        ps_out, ps_err = pure_output(path, DIALECT, keys, render=render)
        ns_out, ns_err, _ = native_summary_output(path, DIALECT, keys)
        assert ns_err == ps_err
        assert ns_out == ps_out
    return [json.loads(x) for x in n_out.splitlines()], n_err, stats


def cli_same(cli: Cli, path: str | Path, *extra: str) -> None:
    name = str(path)
    for argv in (("read", name, "-T", "jsonl"), ("read", name), ("stats", name, "--json")):
        pure = cli(*argv, *extra, environ=PURE)
        native = cli(*argv, *extra, environ={})
        assert native == pure, argv


def notes(row: dict) -> list[str]:
    return [n["code"] for n in row["notes"]]


# --- captures ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", [p.name for p in sorted(CAPTURES.glob("*.raw")) + sorted(CAPTURES.glob("*.bin"))])
def test_bundled_raw_captures(name: str, cli: Cli) -> None:
    cli_same(cli, CAPTURES / name)


@pytest.mark.parametrize("name", REAL_RAW)
def test_real_raw_captures(name: str, real_captures: Path, cli: Cli) -> None:
    assert (real_captures / name).is_file(), name  # (a name that is not there would compare two errors)
    cli_same(cli, real_captures / name)


def test_real_signed_stream_with_its_key(real_captures: Path, cli: Cli) -> None:
    path = real_captures / "gomavlib_signed_testvectors_key4F_DERIVED.raw"
    cli_same(cli, path, "--key", KEY4F)
    rows = [json.loads(x) for x in cli("read", str(path), "-T", "jsonl", "--key", KEY4F, environ={}).out.splitlines()]
    assert [r["signature"]["status"] for r in rows] == ["valid", "valid"]  # PROVENANCE.md: both valid


def test_the_walker_takes_the_clean_stretches_of_real_streams(real_captures: Path) -> None:
    # the corrupt serial capture: damage here and there, mostly clean frames (33,404 frames shown by the pure
    # path); the walker must write nearly all of them itself
    path = real_captures / "ap_hw_copter_cubeorange_raw_serial_corrupt_adsb_v1.raw"
    _, _, stats = native_output(path, DIALECT)
    assert stats["frames_native"] > 0.95 * stats["frames"]
    assert stats["records_handed_back"] < 0.01 * stats["frames"]


# --- streams built by hand ----------------------------------------------------------------------------------


def test_a_clean_stream_is_written_by_the_walker_alone() -> None:
    rows, err, stats = both(clean(50))
    assert [r["frame"] for r in rows] == list(range(1, 51)) and all(r["index"] == 1 for r in rows)
    assert stats["frames_native"] == 50 and stats["records_handed_back"] == 0 and not err


def test_noise_between_frames() -> None:
    # 7 bytes with no STX between frame 10 and frame 11: the framer skips them (skipped-bytes on frame 11, at
    # the noise's offset) and reads on; the frames before and after it are clean, and the walker's
    data = clean(10) + b"\x01\x02\x03\x04\x05\x06\x07" + clean(10, 10)
    rows, _, stats = both(data)
    assert len(rows) == 20 and [r["frame"] for r in rows] == list(range(1, 21))
    assert notes(rows[10]) == ["skipped-bytes"] and rows[10]["notes"][0]["offset"] == 400
    assert sum(map(len, map(notes, rows))) == 1
    assert stats["frames_native"] >= 19 - 1 and stats["records_handed_back"] <= 2


def test_bad_crc_frames() -> None:
    # a bad frame followed by a valid one: shown, bad-crc (framing.py); two bad frames in a row: the first is
    # skipped bytes, the second is shown (the valid frame after it); a bad frame as the stream's last: shown
    # (it ends where the stream ends)
    a = clean(5)
    data = a + bad_crc(v2(30, seq=5)) + clean(3, 6) + bad_crc(v2(30, seq=9)) + bad_crc(v2(30, seq=10)) + clean(2, 11)
    data += bad_crc(v2(30, seq=13))
    rows, _, _ = both(data)
    assert [r["seq"] for r in rows] == [0, 1, 2, 3, 4, 5, 6, 7, 8, 10, 11, 12, 13]
    assert [r["crc_status"] for r in rows].count("bad") == 3
    assert notes(rows[9]) == ["skipped-bytes", "bad-crc"]


def test_a_frame_split_across_two_chunks() -> None:
    # clean frames across the 64 KiB boundary, a frame cut by it: one frame on both engines
    for cut in (1, 2, 3, 10, 39):
        head = filler(CHUNK - 40 + cut)
        assert len(b"".join(head)) == CHUNK - 40 + cut
        rows, err, stats = both(b"".join(head) + clean(5, 200))
        assert len(rows) == len(head) + 5 and [r["frame"] for r in rows] == list(range(1, len(rows) + 1))
        assert not err and all(not r["notes"] for r in rows)
        assert stats["frames_native"] >= len(rows) - 3


def test_damage_at_the_chunk_boundary() -> None:
    for at in (CHUNK - 30, CHUNK - 5, CHUNK - 1, CHUNK, CHUNK + 3):
        head = b"".join(filler(at))
        for damage in (b"\x11\x22\x33", b"\xfd", b"\xfe\x05", bad_crc(v2(30, seq=7)), v2(30, seq=8)[:17],
                       v2(11039, seq=9)[:5] + b"\xfd\x09"):
            both(head + damage + clean(6, 100))


def test_a_stray_stx_and_a_hidden_frame() -> None:
    # a frame with an unknown incompat flag (0x04) holding a whole HEARTBEAT in its payload: the framer shows it
    # (CRC valid, note unknown-incompat-flags); MAVLink's C parser drops it at its flags byte and reads on
    # from there: the HEARTBEAT inside is a frame it acts on (hidden.py), shown with a hidden-frame note
    inner = v2(0, seq=77)
    outer = v2(1, inner + bytes(43 - len(inner)), seq=5, iflags=0x04)
    data = clean(20) + outer + clean(20, 30)
    rows, _, _ = both(data)
    hidden = [r for r in rows if "hidden-frame" in notes(r)]
    assert len(hidden) == 1 and hidden[0]["msgname"] == "HEARTBEAT" and hidden[0]["seq"] == 77
    # a stray STX whose LEN reaches over the next frames (the framer skips it, the C parser reads it to its
    # announced end)
    both(clean(20) + b"\xfd\x40\x00" + clean(20, 30))
    both(clean(20) + b"\xfe\xff" + clean(30, 30) + b"\xfd\xfd\xfd\xfd" + clean(5))


def test_garbage_and_a_cut_frame_at_the_end() -> None:
    rows, _, _ = both(clean(10) + b"\x01\x02\x03")  # three bytes after the last frame: an anomaly, no frame
    assert len(rows) == 10 and not any(r["notes"] for r in rows)
    rows, _, _ = both(clean(10) + v2(30, seq=10)[:25])
    assert notes(rows[-1]) == ["truncated-frame"] and len(rows) == 11
    both(clean(10) + b"\xfd")
    both(b"")
    both(b"\x00" * 100)


def test_unknown_ids_v1_and_python_only_messages() -> None:
    unknown = nh.frame_v2(None, 9999, bytes(12), 3, 1, 1)
    data = clean(5) + unknown + clean(5, 6) + b"".join(v1(0, i) for i in range(5)) + clean(3, 20)
    data += v2(253, b"\x06hello" + bytes(45), 40) + v2(256, bytes(42), 41) + clean(3, 50)
    rows, _, stats = both(data)
    assert [r["msgid"] for r in rows].count(9999) == 1
    assert [r["version"] for r in rows].count(1) == 5
    assert stats["frames_native"] >= 13


def test_signed_frames_with_and_without_the_key() -> None:
    ts = (1_700_000_000 - nh.SIGNING_EPOCH) * 100_000
    signed = [v2(0, seq=i, iflags=1, link_id=1, timestamp=ts + i, key=nh.KEY) for i in range(30)]
    data = b"".join(signed[:10]) + clean(3, 50) + b"".join(signed[10:20]) + b"\x05\x06" + b"".join(signed[20:])
    data += v1(0, 99)  # a MAVLink 1 frame of the signing sender
    for keys in ("none", "key", "leaked"):
        rows, _, stats = both(data, keys)
        assert len(rows) == 34
        if keys == "key":
            assert [r["signature"]["status"] for r in rows if r["signature"]] == ["valid"] * 30
            assert stats["frames_native"] > 20  # the known stream's next frames are judged in C
    with capture_file(data, ".raw") as path:
        cli_same(Cli(), path, "--key", nh.KEY_SPEC)
        cli_same(Cli(), path)


# --- generated streams ----------------------------------------------------------------------------------------

# messages of every kind the summary shows (enums, commands and their params, degrees, char arrays: a payload with
# bytes after a string's NUL is Python's), RADIO_STATUS (no unsigned note), one of ardupilotmega
_PLAIN = [0, 1, 22, 24, 30, 33, 74, 75, 76, 77, 109, 147, 253, 11039]


@st.composite
def segment(draw: st.DrawFn) -> bytes:
    kind = draw(st.sampled_from(["clean", "clean", "clean", "v1", "noise", "bad", "cut", "stray", "flags",
                                 "unknown", "signed", "run"]))
    msgid = draw(st.sampled_from(_PLAIN))
    md = M[msgid]
    payload = draw(st.binary(min_size=1, max_size=md.length))
    seq = draw(st.integers(0, 255))
    if kind == "clean":
        return v2(msgid, payload, seq, draw(st.sampled_from([1, 2, 255])))
    if kind == "v1" and msgid < 256:
        return nh.frame_v1(md, draw(st.binary(min_size=md.base_length, max_size=md.base_length)), seq, 1, 1)
    if kind == "noise":
        return draw(st.binary(min_size=1, max_size=40))
    if kind == "bad":
        return bad_crc(v2(msgid, payload, seq))
    if kind == "cut":
        f = v2(msgid, payload, seq)
        return f[: draw(st.integers(1, len(f) - 1))]
    if kind == "stray":
        return bytes([draw(st.sampled_from([0xFD, 0xFE])), draw(st.integers(0, 255))])
    if kind == "flags":
        return v2(msgid, payload, seq, iflags=draw(st.sampled_from([0x02, 0x04, 0x20])))
    if kind == "unknown":
        return nh.frame_v2(None, draw(st.sampled_from([9999, 42424])), payload, seq, 1, 1)
    if kind == "run":
        return bytes([draw(st.sampled_from([0xFD, 0xFE]))]) * draw(st.integers(2, 600))
    ts = (1_700_000_000 - nh.SIGNING_EPOCH) * 100_000 + draw(st.integers(0, 50))
    return v2(msgid, payload, seq, 7, iflags=1, link_id=0, timestamp=ts, key=nh.KEY)


@settings(max_examples=60, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(st.lists(segment(), max_size=40), st.sampled_from(["none", "key"]))
def test_generated_streams(parts: list[bytes], keys: str) -> None:
    both(b"".join(parts), keys)


@settings(max_examples=30, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(st.integers(0, 400), st.lists(segment(), min_size=1, max_size=25))
def test_generated_streams_across_the_chunk_boundary(before: int, parts: list[bytes]) -> None:
    # the generated part starts `before` bytes ahead of the 64 KiB boundary
    both(b"".join(filler(CHUNK - max(before, 26))) + b"".join(parts) + clean(3, 9))


# --- column mode (stats, every analysis over FrameBatches, the export) ----------------------------------------
#
# native.windows walks a raw stream in column mode as the JSON Lines walk does: the clean stretches become rows
# (record = the stream's frame counter, index 1, no time, transport raw, no endpoints), frames with only the
# notes of the note column as coded rows, the pieces around damage handed back to the stream's framer. The
# reference is the Python pipeline's Frames (Dissector, SecurityStage) as FrameBatch.of_frames makes columns of
# them: every column, every endpoint text, every whole Frame, and the anomalies in order.

_COLUMNS = ("record", "time", "timed", "transport", "version", "seq", "sysid", "compid", "msgid", "size", "crc",
            "verdict", "signed", "clean")


def _pure_frames(path: str, keys: str) -> tuple[list[Frame], list[Anomaly]]:
    from mavscope.capture.detect import open_capture
    from mavscope.pipeline.dissect import Dissector
    from mavscope.security.stage import SecurityStage
    from tests.native.engines import material

    frames: list[Frame] = []
    anomalies: list[Anomaly] = []
    with open_capture(path) as reader:
        for item in SecurityStage(material(keys)).run(Dissector(DIALECT).run(reader)):
            if type(item) is Anomaly:
                anomalies.append(item)
            else:
                frames.append(item)
    return frames, anomalies


def columns_both(data: bytes, keys: str = "none", limit: int = 65_536) -> tuple[list[Frame], dict[str, int], list[int]]:
    """The column windows (native.windows.batches, windows of `limit` rows) of the raw stream `data` against the
    Python pipeline: identical columns, endpoint texts, Frames and anomalies. The pipeline's Frames, the walker's
    counters and the windows' sizes."""
    from mavscope.native import windows
    from mavscope.pipeline.batch import FrameBatch, Tables
    from mavscope.security.stage import SecurityStage
    from tests.native.engines import material

    with capture_file(data, ".raw") as path:
        pure, pure_anomalies = _pure_frames(path, keys)
        reported: list[object] = []
        stats: dict[str, int] = {}
        got = list(windows.batches(path, "raw", DIALECT, SecurityStage(material(keys)), reported.append, Tables(),
                                   limit, stats))
    ref = FrameBatch.of_frames(pure, Tables())
    for name in _COLUMNS:  # (`coded`: the pure batch codes nothing; a coded row's Frame is compared below)
        assert [v for b in got for v in getattr(b, name).tolist()] == getattr(ref, name).tolist(), name
    for name in ("src", "dst"):
        assert [b.tables.text(i) for b in got for i in getattr(b, name).tolist()] == \
            [ref.tables.text(i) for i in getattr(ref, name).tolist()]
    assert [f for b in got for f in b.frames(list(range(b.n)))] == pure
    assert [a for a in reported if type(a) is Anomaly] == pure_anomalies
    return pure, stats, [b.n for b in got]


def test_columns_of_a_clean_stream_are_taken_whole() -> None:
    frames, stats, sizes = columns_both(clean(50))
    assert [f.record for f in frames] == list(range(1, 51))
    assert stats["frames_native"] == 50 and stats["records_handed_back"] == 0


def test_columns_stop_at_the_window_limit_without_handing_back() -> None:
    # 50 clean frames in windows of 7 rows: the stretch is cut where the columns are full and goes on in the next
    # chunk (the framer is idle there), never handed back
    _, stats, sizes = columns_both(clean(50), limit=7)
    assert sizes == [7] * 7 + [1]
    assert stats["frames_native"] == 50 and stats["records_handed_back"] == 0
    for limit in (1, 2, 3, 5):  # a bad frame at the limit: kept where a valid frame follows it
        data = clean(4) + bad_crc(v2(30, seq=4)) + clean(4, 5) + bad_crc(v2(30, seq=9))
        _, stats, _ = columns_both(data, limit=limit)
        assert stats["frames_native"] == 9  # the last bad frame (no frame after it) is the framer's


def test_coded_rows_of_a_raw_stream() -> None:
    # 1/1 signs (no key: verdict no-key), then sends unsigned frames: unsigned-in-signed-stream (code 1); 2/1 sends
    # a bad-CRC frame a valid frame follows (bad-crc, code 4); 1/1 a bad-CRC one (both notes: 5); a MAVLink 1 frame
    # of 1/1 (v1-in-signed-stream: 2), RADIO_STATUS of 1/1 (no note: security/stage.py), 3/1's frames (none).
    # The codes by hand from those rules; every frame is the walker's (no piece handed back).
    ts = (1_700_000_000 - nh.SIGNING_EPOCH) * 100_000
    signed = [v2(0, seq=i, iflags=1, link_id=1, timestamp=ts + i, key=nh.KEY) for i in range(3)]
    bad2, bad1 = bad_crc(v2(30, seq=10, sysid=2)), bad_crc(v2(30, seq=11))
    assert bad2[-1] not in (0xFD, 0xFE) and bad1[-1] not in (0xFD, 0xFE)  # (a bad frame ending in an STX is Python's)
    parts = [*signed, v2(30, seq=3), v2(33, seq=4), bad2, v2(30, seq=5, sysid=3), bad1, v2(30, seq=6, sysid=3),
             v1(0, 7), v2(109, seq=8), v2(30, seq=9, sysid=3)]
    codes = [0, 0, 0, 1, 1, 4, 0, 5, 0, 2, 0, 0]
    for limit in (65_536, 4, 1):
        frames, stats, _ = columns_both(b"".join(parts), limit=limit)
        assert stats["frames_native"] == 12 and stats["records_handed_back"] == 0
        assert [[n.code for n in f.notes] for f in frames] == [
            [], [], [], ["unsigned-in-signed-stream"], ["unsigned-in-signed-stream"], ["bad-crc"], [],
            ["bad-crc", "unsigned-in-signed-stream"], [], ["v1-in-signed-stream"], [], []]
    from mavscope.native import windows
    from mavscope.pipeline.batch import Tables
    from mavscope.security.stage import SecurityStage
    from tests.native.engines import material

    with capture_file(b"".join(parts), ".raw") as path:
        got = list(windows.batches(path, "raw", DIALECT, SecurityStage(material("none")), lambda _i: None, Tables()))
    assert [c for b in got for c in b.coded.tolist()] == codes


def test_columns_with_damage_hand_back_only_the_pieces() -> None:
    # noise between two clean stretches: one piece handed back (to the next CRC-valid frame's end), the rest rows
    data = clean(30) + b"\x01\x02\x03\x04\x05" + clean(30, 30)
    frames, stats, _ = columns_both(data)
    assert len(frames) == 60 and stats["records_handed_back"] == 1 and stats["frames_native"] == 59
    for keys in ("none", "key", "leaked"):  # signed frames with a key: the column walk hands them back
        ts = (1_700_000_000 - nh.SIGNING_EPOCH) * 100_000
        signed = b"".join(v2(0, seq=i, iflags=1, link_id=1, timestamp=ts + i, key=nh.KEY) for i in range(5))
        columns_both(clean(5) + signed + clean(5, 10) + v1(0, 99), keys)


def test_columns_across_the_chunk_boundary() -> None:
    for cut in (1, 3, 39):  # a frame cut by the 64 KiB boundary: one frame, the framer's
        head = filler(CHUNK - 40 + cut)
        frames, stats, _ = columns_both(b"".join(head) + clean(5, 200), limit=1000)
        assert len(frames) == len(head) + 5 and stats["frames_native"] >= len(frames) - 3
    for at in (CHUNK - 5, CHUNK):
        for damage in (b"\x11\x22\x33", bad_crc(v2(30, seq=7)), v2(30, seq=8)[:17]):
            columns_both(b"".join(filler(at)) + damage + clean(6, 100), limit=3000)


@pytest.mark.parametrize("name", REAL_RAW)
def test_columns_of_the_real_raw_captures(name: str, real_captures: Path) -> None:
    # the walker takes the clean stretches of real streams (the corrupt serial capture: 33,404 frames on the
    # pure path, damage here and there) as rows, and hands back exactly the pieces the JSON Lines walk hands
    # back (the same rules take the same frames; the windows' limit cuts no piece) (serial_dump.raw: bundled)
    path = real_captures / name if (real_captures / name).exists() else CAPTURES / name
    pure, stats, _ = columns_both(path.read_bytes(), limit=4096)
    _, _, jsonl = native_output(path, DIALECT)
    assert stats["frames_native"] == jsonl["frames_native"] and stats["frames_native"] > 0.95 * len(pure)
    assert stats["records_handed_back"] == jsonl["records_handed_back"]


@settings(max_examples=40, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(st.lists(segment(), max_size=40), st.sampled_from(["none", "key"]), st.sampled_from([1, 3, 7, 65_536]))
def test_generated_streams_in_column_mode(parts: list[bytes], keys: str, limit: int) -> None:
    columns_both(b"".join(parts), keys, limit)
