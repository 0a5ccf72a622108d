"""Signed frames with keys: the native walker judges the next frame of a known stream itself, and its
output stays byte-identical to the pure path's (`read -T jsonl` and the summary lines of `read`).

- Every bundled capture with signed frames (captures/README.md: signed_udp, clock_skew, securemav_udp,
  ftp_params, key_exchange_udp; commands_ack's SETUP_SIGNING) through the command line, native and
  MAVSCOPE_PURE=1, with the right key, a wrong one, two keys (either order), the key and
  --use-leaked-keys, the key exchange's --ecdh-private: stdout, stderr, exit status equal.
- The shared state: a stream verified in C, then a replay judged in Python (which must see C's last
  timestamp), a key change (Python moves the stream's key, C follows), a key learnt from SETUP_SIGNING.
- Generated captures (hypothesis): streams of several senders and links, signed by pymavlink with two
  keys, with replays (the same bytes again), older timestamps, forged MACs, frames of a key not given,
  key changes, unsigned frames and SETUP_SIGNING mixed in, one to three frames a datagram, in pcap and
  tlog. The verdicts in the native output equal the independent model of tests/native/signed.py (MACs
  checked by pymavlink), and both engines print the same bytes.
- The bench capture's generator (benchmarks/bench_capture.py: two senders signing with bytes(range(32)))
  at 20,000 frames, as it is and with replayed and forged datagrams inserted.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import random
from pathlib import Path

import orjson
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mavscope.mavlink.dialect import load_dialect
from mavscope.security.keys import KeyMaterial, SigningKey
from mavscope.security.stage import SecurityStage
from tests.conftest import CAPTURES, ROOT, Cli
from tests.native import signed as sg
from tests.native.engines import (
    capture_file,
    native_output,
    native_summary_output,
    pure_output,
    same,
    summary_render,
)

pytest.importorskip("mavscope._native", reason="the native extension is not built (no compiler at install)")

DIALECT = load_dialect()
DEMO = hashlib.sha256(b"mavscope-demo").digest()  # captures/README.md: the bundled captures' signing key
WRONG = hashlib.sha256(b"not the key").digest()
ECDH = "hex:3fd8e0bc8bc5bab654bbe4c04d4f780293dc14b287ad8ce5cb496342442c04b3"  # captures/README.md
CIPHER = "2=aes-128-ctr:hex:7c852089ffdb16126dbee7c968a751b5"
SIGNED_CAPTURES = ["signed_udp.pcap", "clock_skew.pcap", "securemav_udp.pcap", "ftp_params.pcap",
                   "key_exchange_udp.pcap", "commands_ack.pcap"]
KEY_SETS = {
    "right": ["--key", "passphrase:mavscope-demo"],
    "wrong": ["--key", "hex:" + WRONG.hex()],
    "wrong-then-right": ["--key", "decoy=hex:" + WRONG.hex(), "--key", "demo=passphrase:mavscope-demo"],
    "right-then-wrong": ["--key", "demo=hex:" + DEMO.hex(), "--key", "decoy=hex:" + WRONG.hex()],
    "right-and-leaked": ["--key", "passphrase:mavscope-demo", "--use-leaked-keys"],
    "ecdh": ["--ecdh-private", ECDH, "--cipher", CIPHER],
}
FORMATS = {"jsonl": ("-T", "jsonl"), "summary": ()}


@pytest.mark.parametrize("fmt", sorted(FORMATS))
@pytest.mark.parametrize("keys", sorted(KEY_SETS))
@pytest.mark.parametrize("name", SIGNED_CAPTURES)
def test_signed_bundled_captures(name: str, keys: str, fmt: str, cli: Cli) -> None:
    same(cli, CAPTURES / name, *KEY_SETS[keys], fmt=FORMATS[fmt])


def statuses(out: bytes) -> list[tuple[str, str | None] | None]:
    rows = [orjson.loads(line) for line in out.splitlines()]
    return [None if r["signature"] is None else (r["signature"]["status"], r["signature"].get("key"))
            for r in rows]


def test_the_key_verifies_in_c_on_signed_udp() -> None:
    """signed_udp.pcap, every frame signed on two streams: with the key only the records holding each
    stream's first frame go to Python; every other frame is judged valid in C."""
    path = CAPTURES / "signed_udp.pcap"
    keys = KeyMaterial(signing=[SigningKey("key1", DEMO)])
    out, err, stats = native_output(path, DIALECT, keys)
    assert (out, err) == pure_output(path, DIALECT, keys)
    assert set(statuses(out)) == {("valid", "key1")}
    assert stats["records_handed_back"] == 2  # each stream's first frame: a new stream, judged in Python
    assert stats["frames_native"] >= 364 - 2 * 3  # at most 3 frames a datagram


KEY_A, KEY_B, KEY_C = (hashlib.sha256(s).digest() for s in (b"key A", b"key B", b"key C"))


def run_both(cap: sg.Capture, keys: KeyMaterial | None = None, tlog: bool = False) -> tuple[bytes, dict[str, int]]:
    """Both engines through the API, JSON Lines and summary lines: equal; the native JSON and its counters."""
    data = cap.tlog() if tlog else cap.pcap()
    make = (lambda: keys) if keys is not None else KeyMaterial
    with capture_file(data) as path:
        out, err, stats = native_output(path, DIALECT, make())
        assert (out, err) == pure_output(path, DIALECT, make())
        s_out, s_err, _ = native_summary_output(path, DIALECT, make())
        assert (s_out, s_err) == pure_output(path, DIALECT, make(), render=summary_render(path, DIALECT))
    return out, stats


def test_state_is_shared_between_c_and_python() -> None:
    a = lambda ts: sg.signed_frame(KEY_A, 1, 1, 0, sg.TS0 + ts)  # noqa: E731
    b = lambda ts: sg.signed_frame(KEY_B, 1, 1, 0, sg.TS0 + ts)  # noqa: E731
    f3 = a(3)
    cap = sg.Capture([[a(1)], [a(2)], [f3], [f3], [a(4)], [b(5)], [b(6)], [a(7)], [a(7)]])
    keys = KeyMaterial(signing=[SigningKey("ka", KEY_A), SigningKey("kb", KEY_B)])
    out, stats = run_both(cap, keys)
    assert statuses(out) == [("valid", "ka"), ("valid", "ka"), ("valid", "ka"),
                             ("replay", "ka"),  # Python saw the timestamp C accepted (3), not only its own (1)
                             ("valid", "ka"), ("valid", "kb"),
                             ("valid", "kb"),  # C tried the key Python moved the stream to
                             ("valid", "ka"), ("replay", "ka")]
    # Python: the new stream, the replay, the two key changes (a key other than the stream's), the last replay
    assert (stats["records_handed_back"], stats["frames_native"]) == (5, 4)
    assert statuses(out) == sg.expected_verdicts(cap.frames(), [("ka", KEY_A), ("kb", KEY_B)], False)


def test_state_ends_where_both_paths_left_it() -> None:
    from mavscope.native import walk as native

    cap = sg.Capture([[sg.signed_frame(KEY_A, 1, 1, 0, sg.TS0 + i)] for i in range(1, 6)])
    stage = SecurityStage(KeyMaterial(signing=[SigningKey("ka", KEY_A)]))
    with capture_file(cap.pcap()) as path, open(os.devnull, "wb") as out:
        class Quiet:
            def anomaly(self, item: object) -> None: ...

            def frame(self, frame: object) -> None: ...

        native.write_jsonl(path, DIALECT, stage, out, Quiet(), threaded=False)
    store = stage.verifier.store
    assert type(store).__name__ == "SigningState" and len(store) == 1
    assert store.get((1, 1, 0)) == (sg.TS0 + 5, 0)


def test_leaked_key_verifies_in_c_after_python_learns_it() -> None:
    frames = [[sg.signed_frame(KEY_A, 1, 1, 0, sg.TS0 + 1)],  # before the leak: no key yet
              [sg.setup_signing_frame(KEY_A)],
              [sg.signed_frame(KEY_A, 1, 1, 0, sg.TS0 + 2)],  # Python: a new stream
              [sg.signed_frame(KEY_A, 1, 1, 0, sg.TS0 + 3), sg.signed_frame(KEY_A, 1, 1, 0, sg.TS0 + 4)],  # C
              [sg.signed_frame(KEY_A, 1, 1, 0, sg.TS0 + 5)]]  # C
    cap = sg.Capture(frames)
    out, stats = run_both(cap, KeyMaterial(use_leaked_keys=True))
    assert statuses(out) == [("no-key", None), None, ("valid", "leaked-2"), ("valid", "leaked-2"),
                             ("valid", "leaked-2"), ("valid", "leaked-2")]
    assert statuses(out) == sg.expected_verdicts(cap.frames(), [], True)
    assert stats["frames_native"] == 3


def test_a_key_name_c_does_not_write_goes_to_python() -> None:
    cap = sg.Capture([[sg.signed_frame(KEY_A, 1, 1, 0, sg.TS0 + i)] for i in range(1, 5)])
    for name in ("n" * 300, "\u00e9t\u00e9 \"quoted\" \\ \x01"):
        out, stats = run_both(cap, KeyMaterial(signing=[SigningKey(name, KEY_A)]))
        assert statuses(out) == [("valid", name)] * 4
        assert stats["frames_native"] == (0 if len(name) > 200 else 3)


def test_two_frames_of_one_stream_in_one_datagram() -> None:
    """Within a datagram the second frame is judged against the first's timestamp, before either is
    committed: a replay inside the datagram sends the whole datagram to Python, which must find the
    state as before the datagram."""
    f = [sg.signed_frame(KEY_A, 1, 1, 0, sg.TS0 + i) for i in range(6)]
    cap = sg.Capture([[f[0]], [f[1], f[2]], [f[3], f[3]], [f[4], f[5]], [f[5]]])
    out, stats = run_both(cap, KeyMaterial(signing=[SigningKey("ka", KEY_A)]))
    assert statuses(out) == sg.expected_verdicts(cap.frames(), [("ka", KEY_A)], False)
    assert [s[0] for s in statuses(out) if s] == ["valid"] * 4 + ["replay", "valid", "valid", "replay"]
    assert stats["frames_native"] == 4


# --- generated streams ---------------------------------------------------------------------------

SENDERS = [(1, 1), (255, 190), (2, 1)]
SENDER_KEY = [KEY_A, KEY_B, KEY_A]
CONFIGS: dict[str, tuple[list[tuple[str, bytes]], bool]] = {
    "A": ([("ka", KEY_A)], False),
    "C": ([("kc", KEY_C)], False),
    "CA": ([("kc", KEY_C), ("ka", KEY_A)], False),
    "AB": ([("ka", KEY_A), ("kb", KEY_B)], False),
    "BA": ([("kb", KEY_B), ("ka", KEY_A)], False),
    "leaked": ([], True),
    "A+leaked": ([("ka", KEY_A)], True),
}
KINDS = ["next"] * 10 + ["replay", "replay", "older", "forge", "wrongkey", "switch", "unsigned", "setup"]


@st.composite
def signed_capture(draw: st.DrawFn) -> sg.Capture:
    clock: dict[tuple[int, int], int] = {}
    done: list[bytes] = []
    frames: list[bytes] = []
    for _ in range(draw(st.integers(1, 40))):
        kind = draw(st.sampled_from(KINDS))
        who = draw(st.integers(0, len(SENDERS) - 1))
        sysid, compid = SENDERS[who]
        link = draw(st.integers(0, 1))
        key = SENDER_KEY[who]
        # a stream's first timestamp up to 200 s either side of the capture's (a skew note beyond 60 s)
        ts = clock.setdefault((who, link), sg.TS0 + draw(st.integers(-20_000_000, 20_000_000)))
        ts += draw(st.integers(1, 3000))
        look = draw(st.integers(0, 2)), draw(st.floats(-4.0, 4.0, width=32))
        if kind == "replay" and done:
            frames.append(draw(st.sampled_from(done)))
            continue
        if kind == "older":
            ts -= draw(st.integers(1, 6000))
        elif kind == "wrongkey":
            key = KEY_C
        elif kind == "switch":
            key = KEY_B if key == KEY_A else KEY_A
        elif kind == "unsigned":
            frames.append(sg.unsigned_frame(sysid, compid))
            continue
        elif kind == "setup":
            frames.append(sg.setup_signing_frame(draw(st.sampled_from([KEY_A, KEY_B, KEY_C, bytes(32)]))))
            continue
        if kind != "older":
            clock[(who, link)] = ts
        f = sg.signed_frame(key, sysid, compid, link, ts, *look)
        if kind == "forge":
            f = sg.forged(f)
        frames.append(f)
        done.append(f)
    cap = sg.Capture()
    i = 0
    while i < len(frames):
        n = draw(st.integers(1, 3))
        cap.records.append(frames[i: i + n])
        i += n
    return cap


SETTINGS = settings(max_examples=int(os.environ.get("MAVSCOPE_NATIVE_EXAMPLES", "300")), deadline=None,
                    derandomize=True, suppress_health_check=list(HealthCheck))
FEWEST = settings(SETTINGS, max_examples=max(SETTINGS.max_examples // 30, 5))  # through the command line


def material(config: str) -> KeyMaterial:
    keys, leaked = CONFIGS[config]
    return KeyMaterial(signing=[SigningKey(n, k) for n, k in keys], use_leaked_keys=leaked)


@SETTINGS
@given(signed_capture(), st.sampled_from(sorted(CONFIGS)), st.booleans())
def test_generated_signed_streams(cap: sg.Capture, config: str, tlog: bool) -> None:
    if tlog:  # a tlog entry holds one frame
        cap = sg.Capture([[f] for rec in cap.records for f in rec])
    out, _ = run_both(cap, material(config), tlog=tlog)
    keys, leaked = CONFIGS[config]
    assert statuses(out) == sg.expected_verdicts(cap.frames(), keys, leaked)


CLI = Cli()


@FEWEST
@given(signed_capture(), st.sampled_from(sorted(CONFIGS)))
def test_generated_signed_streams_through_the_command_line(cap: sg.Capture, config: str) -> None:
    keys, leaked = CONFIGS[config]
    options = [a for n, k in keys for a in ("--key", f"{n}=hex:{k.hex()}")]
    options += ["--use-leaked-keys"] if leaked else []
    with capture_file(cap.pcap()) as path:
        same(CLI, path, *options)
        same(CLI, path, *options, fmt=())


# --- the bench capture's generator -----------------------------------------------------------------

BENCH_KEY = bytes(range(32))  # benchmarks/bench_capture.py SIGNING_KEY


def bench_generate(path: Path, frames: int) -> None:
    spec = importlib.util.spec_from_file_location("bench_capture", ROOT / "benchmarks" / "bench_capture.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.generate(path, frames, seed=17)


def with_replays_and_forgeries(data: bytes, seed: int) -> bytes:
    """The bench pcap with some of its signed datagrams sent again later (byte for byte) and some with a
    signature byte changed (as forged), both in place of an ordinary record."""
    rng = random.Random(seed)
    head, records, pos = data[:24], [], 24
    while pos < len(data):
        incl = int.from_bytes(data[pos + 8: pos + 12], "little")
        records.append(bytearray(data[pos: pos + 16 + incl]))
        pos += 16 + incl
    signed = [i for i, r in enumerate(records) if r[16 + 42 + 2] & 1]
    for i in rng.sample(signed, len(signed) // 50):
        records[i][-1] ^= 0x33  # the last frame's MAC
    for i in sorted(rng.sample(signed, len(signed) // 50), reverse=True):
        j = min(len(records) - 1, i + rng.randint(1, 500))
        records.insert(j, bytearray(records[j][:8]) + records[i][8:])  # with the time of its new place
    return head + b"".join(records)


@pytest.mark.parametrize("mixed", [False, True], ids=["as-generated", "replays-and-forgeries"])
def test_bench_capture(tmp_path: Path, mixed: bool) -> None:
    path = tmp_path / "bench.pcap"
    bench_generate(path, 20_000)
    data = path.read_bytes()
    if mixed:
        data = with_replays_and_forgeries(data, 5)
        path.write_bytes(data)
    frames = sg.pcap_frames(data)
    for keys in ([("key1", BENCH_KEY)], [("kc", KEY_C)], [("kc", KEY_C), ("key1", BENCH_KEY)]):
        material = KeyMaterial(signing=[SigningKey(n, k) for n, k in keys])
        out, err, stats = native_output(path, DIALECT, material)
        assert (out, err) == pure_output(path, DIALECT, material)
        expected = sg.expected_verdicts(frames, keys, False)
        assert statuses(out) == expected
        if keys[-1][1] == BENCH_KEY:  # the key: C judges all but the frames around the odd ones
            odd = sum(1 for v in expected if v and v[0] != "valid") + 2  # and each stream's first
            assert sum(1 for v in expected if v) > 4_000
            assert stats["frames_native"] >= len(frames) - 3 * odd


def test_the_walker_reads_only_the_senders_python_added_since_the_last_batch() -> None:
    """40 signed HEARTBEATs (pymavlink), each from a new sender on a new link: every one is a new signing
    stream, handed back to Python, so every record is a batch. Before each batch the walker read the whole
    set of senders seen signing (200,000 such frames took `read -T jsonl --key` 429 s); now it reads the
    set once and then the senders Python logged. The output is the pure path's, every frame valid (the
    model of tests/native/signed.py). A clear() of the set (new key material) starts a new epoch, which
    makes a walker read the whole set again."""
    from mavscope.native import walk as native
    from mavscope.security.stage import SignedSenders

    walked = 0

    class Counting(SignedSenders):
        __slots__ = ()

        def __iter__(self):  # type: ignore[no-untyped-def]
            nonlocal walked
            walked += 1
            return super().__iter__()

    cap = sg.Capture([[sg.signed_frame(KEY_A, 1 + i, 1, i, sg.TS0 + i)] for i in range(40)])
    keys = KeyMaterial(signing=[SigningKey("ka", KEY_A)])
    out, stats = run_both(cap, keys)
    assert statuses(out) == sg.expected_verdicts(cap.frames(), [("ka", KEY_A)], False) == [("valid", "ka")] * 40
    assert stats["records_handed_back"] == 40

    stage = SecurityStage(keys)
    stage.signed_senders = Counting()
    with capture_file(cap.pcap()) as path, open(os.devnull, "wb") as devnull:
        class Quiet:
            def anomaly(self, item: object) -> None: ...

            def frame(self, frame: object) -> None: ...

        native.write_jsonl(path, DIALECT, stage, devnull, Quiet(), threaded=False)
        assert walked == 1 and len(stage.signed_senders) == 40 and len(stage.signed_senders.log) == 40
        stage.signed_senders.clear()
        assert stage.signed_senders.epoch == 1 and not stage.signed_senders.log
