"""`mavscope read -T fields` against `tshark -T fields` with pymavlink's Lua dissector, on the same captures.

The reference is tshark itself (4.0, `scripts/install-test-tools.sh`) running the Lua dissector pymavlink
generates for the `all` dialect (tests/support/tshark.py; skipped with the reason where either is
missing): the same `-e` names (the Lua's `mavlink_proto.*` spellings, which mavscope takes as aliases;
frame and UDP fields by Wireshark's names) and the same `-E` options on both, tshark's packets restricted
to those with a MAVLink frame (`-Y mavlink_proto`: mavscope prints no line for a record without one).
Integer fields must be equal as text, line for line; float fields are compared as float32 values (tshark
4.0 prints an FT_FLOAT with `%g`'s 6 digits, mavscope the shortest text that reads back as the float32),
the same value to tshark's precision. The captures hold several MAVLink frames in some datagrams, so
`-E occurrence` and `-E aggregator` are exercised on real occurrences.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import CAPTURES, Cli
from tests.support import tshark

CAPTURE_NAMES = ("px4_sitl_udp.pcap", "mavlink_v1_udp.pcap", "signed_udp.pcap")
INT_FIELDS = ("frame.number", "udp.srcport", "udp.dstport", "mavlink_proto.sysid", "mavlink_proto.compid",
              "mavlink_proto.msgid", "mavlink_proto.sequence", "mavlink_proto.length",
              "mavlink_proto.GLOBAL_POSITION_INT_lat", "mavlink_proto.HEARTBEAT_custom_mode")
FLOAT_FIELDS = ("mavlink_proto.ATTITUDE_roll", "mavlink_proto.ATTITUDE_yawspeed")
OPTIONS = [("separator=,",), ("separator=/s", "occurrence=f"), ("occurrence=l", "aggregator=;"),
           ("header=y", "quote=d")]


def _tshark_lines(exe: str, lua: Path, capture: Path, names: tuple[str, ...], options: tuple[str, ...],
                  flt: str | None = None) -> list[str]:
    cmd = [exe, "-n", "-X", f"lua_script:{lua}", "-r", str(capture)]
    for port in sorted(tshark.mavlink_udp_ports(capture) - tshark.LUA_UDP_PORTS):
        cmd += ["-d", f"udp.port=={port},{tshark.LUA_PROTO}"]
    cmd += ["-Y", flt or tshark.LUA_PROTO, "-T", "fields", *(a for n in names for a in ("-e", n)),
            *(a for o in options for a in ("-E", o))]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300, check=False,
                          env=tshark._tshark_env(lua.parent))
    assert proc.returncode == 0, proc.stderr[-500:]
    return proc.stdout.splitlines()


def _mavscope_lines(cli: Cli, capture: Path, names: tuple[str, ...], options: tuple[str, ...]) -> list[str]:
    got = cli("read", str(capture), "-T", "fields", *(a for n in names for a in ("-e", n)),
              *(a for o in options for a in ("-E", o)))
    assert got.status == 0, got.err
    return got.out.splitlines()


@pytest.mark.parametrize("options", OPTIONS, ids=lambda o: " ".join(o))
@pytest.mark.parametrize("name", CAPTURE_NAMES)
def test_integer_fields_as_tshark_prints_them(name: str, options: tuple[str, ...], tshark_exe: str,
                                              lua_dissector: Path, cli: Cli) -> None:
    capture = CAPTURES / name
    want = _tshark_lines(tshark_exe, lua_dissector, capture, INT_FIELDS, options)
    got = _mavscope_lines(cli, capture, INT_FIELDS, options)
    assert len(got) == len(want) > 10
    for k, (g, w) in enumerate(zip(got, want)):
        assert g == w, (k, g, w)


@pytest.mark.parametrize("name", CAPTURE_NAMES)
def test_float_fields_are_tsharks_values(name: str, tshark_exe: str, lua_dissector: Path, cli: Cli) -> None:
    capture = CAPTURES / name
    names = ("frame.number", *FLOAT_FIELDS)
    want = _tshark_lines(tshark_exe, lua_dissector, capture, names, ("separator=/t",))
    got = _mavscope_lines(cli, capture, names, ("separator=/t",))
    assert len(got) == len(want)
    compared = 0
    for g, w in zip(got, want):
        gs, ws = g.split("\t"), w.split("\t")
        assert gs[0] == ws[0]
        for gv, wv in zip(gs[1:], ws[1:]):
            assert (gv == "") == (wv == "")
            if not gv:
                continue
            assert len(gv.split(",")) == len(wv.split(","))
            for a, b in zip(gv.split(","), wv.split(",")):
                # tshark's %g: our float32 to 6 significant digits is its text's value
                assert float(f"{float(np.float32(a)):.6g}") == float(b), (g, w)
                compared += 1
    assert compared > 0 or name == "mavlink_v1_udp.pcap"


def test_fields_options_are_checked(cli: Cli) -> None:
    """What tshark refuses, mavscope refuses with one line (exit 2): -e without -T fields, -T fields without
    -e, an -E option or value tshark does not define, a field no registry knows (with a suggestion)."""
    capture = str(CAPTURES / "px4_sitl_udp.pcap")
    for argv, words in ((("-e", "mavlink.seq"), "-T fields"), (("-T", "fields"), "-e FIELD"),
                        (("-T", "fields", "-e", "mavlink.seq", "-E", "colour=y"), "unknown option"),
                        (("-T", "fields", "-e", "mavlink.seq", "-E", "quote=x"), "d, s or n"),
                        (("-T", "fields", "-e", "mavlink.seqq"), 'did you mean "mavlink.seq"'),
                        (("-T", "fields", "-e", "HEARTBEAT"), "a message, not a field")):
        got = cli("read", capture, *argv)
        assert got.status == 2 and words in got.err and got.out == "", (argv, got.err)


TIME_FIELDS = ("frame.number", "frame.time", "frame.time_epoch", "frame.time_relative", "frame.time_delta",
               "frame.time_delta_displayed")


@pytest.mark.parametrize("flt", [None, "frame.number != 2 && frame.number != 7"])
def test_time_fields_as_tshark_prints_them(flt: str | None, tshark_exe: str, lua_dissector: Path, cli: Cli) -> None:
    """tshark's frame.time* fields (TZ=UTC on both), with and without a display filter (which changes
    frame.time_delta_displayed, not frame.time_delta)."""
    capture = CAPTURES / "px4_sitl_udp.pcap"
    want = _tshark_lines(tshark_exe, lua_dissector, capture, TIME_FIELDS, (),
                         f"{tshark.LUA_PROTO} && ({flt})" if flt else None)
    got = cli("read", str(capture), *(("-Y", flt) if flt else ()), "-T", "fields",
              *(a for n in TIME_FIELDS for a in ("-e", n)), environ={"TZ": "UTC"})
    assert got.status == 0, got.err
    assert got.out.splitlines() == want


@pytest.mark.parametrize("fmt", ["a", "ad", "adoy", "d", "dd", "e", "r", "u", "ud", "udoy"])
def test_time_column_as_tshark_shows_it(fmt: str, tshark_exe: str, lua_dissector: Path, cli: Cli) -> None:
    """`read -t FMT`'s time column against tshark's `-t FMT` column of the same record (the first frame of a
    record: tshark shows a packet once), both filtered to MAVLink (tshark: the Lua dissector's protocol) and
    to all but two records: `d` counts from the record before (shown or not, MAVLink or not), `dd` from the
    last shown."""
    capture = CAPTURES / "px4_sitl_udp.pcap"
    flt = "frame.number != 2 && frame.number != 7"
    cmd = [tshark_exe, "-n", "-X", f"lua_script:{lua_dissector}", "-r", str(capture), "-t", fmt,
           "-Y", f"{tshark.LUA_PROTO} && ({flt})", "-T", "fields", "-e", "frame.number", "-e", "_ws.col.Time"]
    for port in sorted(tshark.mavlink_udp_ports(capture) - tshark.LUA_UDP_PORTS):
        cmd[-8:-8] = ["-d", f"udp.port=={port},{tshark.LUA_PROTO}"]
    ref = subprocess.run(cmd, capture_output=True, text=True, timeout=300, check=False,
                         env=tshark._tshark_env(lua_dissector.parent))
    assert ref.returncode == 0, ref.stderr[-300:]
    want = dict(line.split("\t") for line in ref.stdout.splitlines())
    got = cli("read", str(capture), "-Y", flt, "-t", fmt, environ={"TZ": "UTC"})
    assert got.status == 0, got.err
    seen: dict[str, str] = {}
    for line in got.out.splitlines():
        m = re.match(r"\s*(\S+) +(.*?) +127\.0\.0\.1:", line)
        assert m is not None, line
        seen.setdefault(m.group(1).partition(".")[0], m.group(2))
    assert seen == want and len(seen) > 100
