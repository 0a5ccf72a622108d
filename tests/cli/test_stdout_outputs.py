"""`-` is standard output for every output option, or a clear refusal (issue 35, item 15).

The options are found by walking the built parsers (every subcommand's), so an output option added later is
covered: it must be declared with `add_output_option` (an option that looks like one and is not fails), and
it must have a row in INVOCATIONS. The rules checked are tshark's for `-w -` (its man page and tshark.c):
the output goes to standard output and nothing else is written there ("You can't write both raw packet data
and dissected packets to the standard output": tshark refuses -V/-x/-T with -w -); binary data is not written
to a terminal; a directory cannot be standard output. Expected bytes: what the same command writes when the
option names a file (the two must be byte for byte equal), and for packet captures the formats' magic numbers
(pcap: a1b2c3d4 little-endian, libpcap's savefile.c; PNG: its 8-byte signature, RFC 2083). A file literally
named `-` is never created.
"""

from __future__ import annotations

import argparse
import io
import re
import shutil
from pathlib import Path

import pytest

from mavscope.cli import Env, build_parser, main
from mavscope.commands.common import OutputKind, OutputOption, output_options
from tests.conftest import CAPTURES, REAL_CAPTURES

PCAP_MAGIC = bytes.fromhex("d4c3b2a1")  # 0xa1b2c3d4 written little-endian (microsecond pcap)
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"

# A working invocation of each output option, `{}` where the output goes (every row is run with `-`).
INVOCATIONS: dict[tuple[str, str], list[list[str]]] = {
    ("read", "-w"): [["read", str(CAPTURES / "px4_sitl_udp.pcap"), "-Y", "HEARTBEAT", "-w", "{}"],
                     ["read", str(CAPTURES / "px4_sitl.tlog"), "-c", "20", "-w", "{}"]],  # tlog: frames wrapped
    ("live", "-w"): [["live", "--udp", "127.0.0.1:0", "--duration", "0.2", "-w", "{}"]],
    ("mission", "--plan"): [["mission", str(CAPTURES / "mission_resend.pcap"), "--plan", "{}"]],
    ("params", "--out"): [["params", str(CAPTURES / "ftp_params.pcap"), "--out", "{}"]],
    ("track", "--geojson"): [["track", str(CAPTURES / "gcs_takeover.pcap"), "--geojson", "{}"]],
    ("track", "--kml"): [["track", str(CAPTURES / "gcs_takeover.pcap"), "--kml", "{}"]],
    ("track", "--gpx"): [["track", str(CAPTURES / "gcs_takeover.pcap"), "--gpx", "{}"]],
    ("plot", "--out"): [["plot", str(CAPTURES / "px4_sitl_udp.pcap"), "HEARTBEAT.type", "--out", "{}"]],
    ("objects", "--out"): [["objects", str(CAPTURES / "ftp_params.pcap"), "--out", "{}"]],
    ("export", "--parquet"): [["export", str(CAPTURES / "ftp_params.pcap"), "--parquet", "{}"]],
    ("export", "-o"): [["export", str(CAPTURES / "ftp_params.pcap"), "-T", "csv", "-o", "{}"]],
    ("report", "--out"): [["report", str(CAPTURES / "gps_spoof.pcap"), "-o", "{}"]],
    ("report", "--json"): [["report", str(CAPTURES / "gps_spoof.pcap"), "--json", "{}"]],
}
FILE_NAMES = {("plot", "--out"): "out.png", ("read", "-w"): "out.pcap", ("live", "-w"): "out.pcap"}


def _comparable(key: tuple[str, str], data: bytes) -> bytes:
    """What two runs write alike: a report names the time of its analysis and the command line (which names
    where it writes), those aside."""
    if key[0] != "report":
        return data
    text = re.sub(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ", "T", data.decode())
    return re.sub(r'"command_line": \[[^\]]*\]|<code>mavscope report [^<]*</code>', "C", text).encode()


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    p = build_parser()
    sub = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def _all_outputs() -> dict[tuple[str, str], OutputOption]:
    return {(name, max(a.option_strings, key=len)): a for name, sp in _subparsers().items() for a in output_options(sp)}


class _Pipe(io.TextIOWrapper):
    """Standard output as a pipe gives it: text over a binary buffer, not a terminal."""

    def __init__(self) -> None:
        super().__init__(io.BytesIO(), encoding="utf-8")

    def data(self) -> bytes:
        self.flush()
        return self.buffer.getvalue()  # type: ignore[attr-defined]


class _Terminal(_Pipe):
    def isatty(self) -> bool:
        return True


def _run(argv: list[str], stdout: _Pipe | None = None, environ: dict[str, str] | None = None,
         ) -> tuple[int, bytes, str]:
    out, err = stdout or _Pipe(), io.StringIO()
    status = main(argv, Env(stdout=out, stderr=err, environ=dict(environ or {})))
    return int(status), out.data(), err.getvalue()


def test_every_option_that_writes_is_an_output_option() -> None:
    """An option naming a file or directory to write (by its metavar or its help) is declared as one, and has
    an invocation here: a new output option is checked by the tests below without being listed by hand."""
    for name, sp in _subparsers().items():
        for a in sp._actions:
            if isinstance(a, OutputOption) or a.nargs == 0 or a.choices is not None or not a.option_strings:
                continue
            looks = re.search(r"OUT|DIR|\.png|\.plan", str(a.metavar or "")) or \
                re.match(r"(write|draw|save|export)\b", a.help or "")
            assert not looks, f"{name} {a.option_strings}: an output? declare it with add_output_option"
    assert set(_all_outputs()) == set(INVOCATIONS), "every output option needs an invocation in INVOCATIONS"


@pytest.mark.parametrize("key", sorted(INVOCATIONS))
def test_dash_is_standard_output_or_a_clear_refusal(key: tuple[str, str], tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    kind = _all_outputs()[key].kind
    if key == ("plot", "--out"):
        pytest.importorskip("matplotlib")
    monkeypatch.chdir(tmp_path)
    for argv in INVOCATIONS[key]:
        dash = [w.replace("{}", "-") for w in argv]
        status, out, err = _run(dash)
        if kind is OutputKind.DIRECTORY:
            assert status == 2 and out == b"" and err.count("\n") == 1, (dash, err)
            assert f"{key[1]} -:" in err and "directory" in err
        else:
            assert status == 0, (dash, err)
            target = tmp_path / FILE_NAMES.get(key, "out.txt")
            fstatus, fout, ferr = _run([w.replace("{}", str(target)) for w in argv])
            assert fstatus == 0, ferr
            written = target.read_bytes()
            if key != ("live", "-w"):  # (two live runs differ in nothing but may differ in packets: none here)
                assert _comparable(key, out) == _comparable(key, written), dash  # the file's bytes, nothing else
            if kind is OutputKind.BINARY:
                assert out.startswith(PNG_MAGIC if key[0] == "plot" else PCAP_MAGIC)
            # an analysis's report, which the file run prints on stdout, goes to stderr (lines naming the file
            # aside); `read` and `live` print no frame with -w - (tshark prints no packet with -w)
            for line in fout.decode().splitlines() if key[0] not in ("read", "live") else ():
                if str(target) not in line and line.strip():
                    assert line in err, (dash, line)
            target.unlink()
            shutil.rmtree(tmp_path / "-", ignore_errors=True)
        assert not (tmp_path / "-").exists(), f"{dash} created a file named -"
        assert list(tmp_path.iterdir()) == [], list(tmp_path.iterdir())


@pytest.mark.parametrize("key", sorted(k for k in INVOCATIONS if k[0] in ("read", "live", "plot")))
def test_binary_output_is_not_written_to_a_terminal(key: tuple[str, str], tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    assert _all_outputs()[key].kind is OutputKind.BINARY
    monkeypatch.chdir(tmp_path)
    for argv in INVOCATIONS[key]:
        status, out, err = _run([w.replace("{}", "-") for w in argv], stdout=_Terminal())
        assert status == 2 and out == b"" and err.count("\n") == 1
        assert "terminal" in err and f"{key[1]} -" in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("argv", "other"), [
    (["read", str(CAPTURES / "px4_sitl_udp.pcap"), "-w", "-", "-V"], "-V"),
    (["read", str(CAPTURES / "px4_sitl_udp.pcap"), "-w", "-", "-x"], "-x"),
    (["read", str(CAPTURES / "px4_sitl_udp.pcap"), "-w", "-", "-T", "jsonl"], "-T jsonl"),
    (["live", "--udp", "127.0.0.1:0", "--duration", "0.1", "-w", "-", "-T", "jsonl"], "-T jsonl"),
    (["mission", str(CAPTURES / "mission_resend.pcap"), "--plan", "-", "--json"], "--json"),
    (["params", str(CAPTURES / "ftp_params.pcap"), "--out", "-", "--json"], "--json"),
    (["track", str(CAPTURES / "gcs_takeover.pcap"), "--gpx", "-", "--json"], "--json"),
    (["track", str(CAPTURES / "gcs_takeover.pcap"), "--gpx", "-", "--kml", "-"], "--kml"),
    (["plot", str(CAPTURES / "px4_sitl_udp.pcap"), "HEARTBEAT.type", "--out", "-", "--json"], "--json"),
])
def test_two_outputs_on_standard_output_are_refused(argv: list[str], other: str, tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """tshark: "You can't write both raw packet data and dissected packets to the standard output." """
    monkeypatch.chdir(tmp_path)
    status, out, err = _run(argv)
    assert status == 2 and out == b"" and err.count("\n") == 1 and other in err, err
    assert list(tmp_path.iterdir()) == []


def test_live_ring_needs_files(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    status, out, err = _run(["live", "--udp", "127.0.0.1:0", "-w", "-", "--ring", "1"])
    assert status == 2 and out == b"" and "--ring" in err and err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("engine", [{}, {"MAVSCOPE_PURE": "1"}], ids=["native", "pure"])
def test_read_w_dash_on_real_captures(real_captures: Path, tmp_path: Path, engine: dict[str, str]) -> None:
    """Every real capture: `read -w -` gives the bytes `read -w FILE` writes, on both engines; a pcap input
    written as pcap carries the input's records (the count of `read -q -w FILE` is the file's)."""
    for capture in sorted(REAL_CAPTURES.iterdir()):
        if capture.suffix == ".md":
            continue
        target = tmp_path / "out.pcap"
        status, out, err = _run(["read", str(capture), "-w", "-"], environ=engine)
        fstatus, fout, ferr = _run(["read", str(capture), "-q", "-w", str(target)], environ=engine)
        assert status == fstatus == 0, (capture.name, err, ferr)
        assert out == target.read_bytes() and out[:4] in (PCAP_MAGIC, bytes.fromhex("0a0d0d0a")), capture.name
        assert fout == b"" and err == ferr, capture.name  # the same problems on stderr, nothing else anywhere
        target.unlink()
