"""The native engine and the pure-Python path print the same `read -T jsonl`, byte for byte.

Run through the real command line (the `cli` fixture) with MAVSCOPE_PURE=1 and without, on every bundled
capture (without keys, with the key of signed_udp.pcap, with --use-leaked-keys) and every real capture
beside the repository: stdout, stderr and exit status equal. The pure path is the reference; the native
engine must also have done its work (frames written natively where the capture has clean ones).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import CAPTURES, REAL_CAPTURES, Cli
from tests.native.engines import PURE, native, same

pytest.importorskip("mavscope._native", reason="the native extension is not built (no compiler at install)")

BUNDLED = sorted(p.name for p in CAPTURES.iterdir() if p.suffix not in (".md", ".json"))
SIGNED_UDP_KEY = "hex:ac2193ecb3be4d7e444e2867d430a8b1618cd2ac1ed9710d580a79630f5420f0"  # captures/README.md
KEY_OPTIONS = {
    "no-keys": [],
    "key": ["--key", SIGNED_UDP_KEY],
    "leaked": ["--use-leaked-keys"],
}


@pytest.mark.parametrize("keys", sorted(KEY_OPTIONS))
@pytest.mark.parametrize("name", BUNDLED)
def test_bundled_capture(name: str, keys: str, cli: Cli) -> None:
    same(cli, CAPTURES / name, *KEY_OPTIONS[keys])


def real_names() -> list[str]:
    if not REAL_CAPTURES.is_dir():
        return []
    return sorted(p.name for p in REAL_CAPTURES.iterdir() if p.suffix != ".md")


@pytest.mark.parametrize("name", real_names() or ["(absent)"])
def test_real_capture(name: str, real_captures: Path, cli: Cli) -> None:
    same(cli, real_captures / name)


def test_the_rover_tlog_with_console_text(real_captures: Path, cli: Cli) -> None:
    """MAVProxy logged the SITL's console one byte an entry: those entries go to the Python pipeline
    (joined into tlog-text problems), the 96,646 frames (as pymavlink counts them, docs: issue 11) are
    written natively around them."""
    from mavscope.mavlink.dialect import load_dialect
    from mavscope.native.walk import NativeWalk

    path = real_captures / "ap_rover_mission_fence_rally_params.tlog"
    result = native(cli, path)  # identity with the pure path: test_real_capture
    assert result.status == 0
    assert result.out.count("\n") == 96_646
    assert "tlog-text" not in result.out and "bytes that are not MAVLink" in result.err
    with NativeWalk(path, load_dialect(), set(), set()) as walk:
        for _ in walk.batches():
            pass
        stats = walk.stats()
    assert stats["frames_native"] == 96_646
    assert stats["records_handed_back"] == 285  # the one-byte text entries


def test_engine_is_named_and_pure_can_be_forced() -> None:
    from mavscope.native.core import engine

    assert engine({}) == "native"
    assert engine({"MAVSCOPE_PURE": "1"}) == "pure-python"
    assert engine({"MAVSCOPE_PURE": "0"}) == "native"


def _same_command(cli: Cli, *argv: str) -> None:
    """`mavscope ARGV` with MAVSCOPE_PURE=1 and without: stdout, stderr and exit status equal."""
    p, n = cli(*argv, environ=PURE), cli(*argv, environ={})
    assert (n.err, n.out, n.status) == (p.err, p.out, p.status)


@pytest.mark.parametrize("name", BUNDLED)
def test_bundled_capture_verbose_hex_and_verify(name: str, cli: Cli) -> None:
    """Issue 12's evidence beyond JSON Lines: `read -V -x` (the detail tree and hex of every frame, which the
    native engine leaves to the Python printer) and `verify --json` are the same under both engines."""
    same(cli, CAPTURES / name, "--key", SIGNED_UDP_KEY, fmt=("-V", "-x"))
    _same_command(cli, "verify", str(CAPTURES / name), "--json", "--key", SIGNED_UDP_KEY)


@pytest.mark.parametrize("name", real_names())
def test_real_capture_verbose_hex_and_verify(name: str, real_captures: Path, cli: Cli) -> None:
    same(cli, real_captures / name, "-c", "3000", fmt=("-V", "-x"))  # the first 3,000 frames: output stays small
    _same_command(cli, "verify", str(real_captures / name), "--json", "--use-leaked-keys")
