"""`read --color`: summary lines coloured by verdict, as the rules of mavscope/output/colour.py say.

A capture built here (pymavlink frames, tests/support/security.py's signing key): a signed HEARTBEAT
(valid with the key: green), an unsigned ATTITUDE of the same sender (unsigned in a signed stream:
orange), the same ATTITUDE with its CRC changed (bad CRC: red, the first rule), and a frame of a sender
that never signs (no colour). The expected colour of each line is written out here from those rules and
the TUI's verdict styles (RED, ORANGE, GREEN of mavscope/tui/verdicts.py as 24-bit SGR). `never`, `auto`
on a pipe, and NO_COLOR under `auto` give no escape at all; `always` wins over NO_COLOR.
"""

from __future__ import annotations

import io
from pathlib import Path

from mavscope.output.colour import wants_colour
from tests.conftest import Cli
from tests.native.test_bad_crc_native import _attitude, _bad
from tests.support.builders import write_udp_pcap
from tests.support.security import SHA_KEY, heartbeat, signer

GCS, VEHICLE = ("10.0.0.1", 14550), ("10.0.0.2", 14580)
RED, ORANGE, GREEN = "\x1b[1;38;2;255;95;95m", "\x1b[1;38;2;255;175;0m", "\x1b[38;2;95;215;95m"


def _capture(tmp: Path) -> Path:
    s, v, other = signer(SHA_KEY, 1, 1), signer(None, 1, 1), signer(None, 2, 1)
    return write_udp_pcap(tmp / "c.pcap", [(VEHICLE, GCS, heartbeat(s)), (VEHICLE, GCS, _attitude(v)),
                                           (VEHICLE, GCS, _bad(_attitude(v, 0.3))), (VEHICLE, GCS, _attitude(other))])


def test_each_verdict_its_colour(cli: Cli, tmp_path: Path) -> None:
    path = str(_capture(tmp_path))
    got = cli("read", path, "--color=always", "--key", "hex:" + SHA_KEY.hex())
    assert got.status == 0, got.err
    lines = got.out.splitlines()
    assert [line[:len(c)] == c for line, c in zip(lines, (GREEN, ORANGE, RED))] == [True, True, True]
    assert all(line.endswith("\x1b[0m") for line in lines[:3])
    assert "\x1b" not in lines[3]  # 2/1 never signs: no rule
    assert sum(line.count("\x1b[") for line in lines) == 6  # one colour and one reset a coloured line
    # without the key the signed frame is no-key: no colour; the rest as before
    plain = cli("read", path, "--color=always").out.splitlines()
    assert "\x1b" not in plain[0] and plain[1].startswith(ORANGE) and plain[2].startswith(RED)


def test_no_colour_unless_asked_for(cli: Cli, tmp_path: Path) -> None:
    path = str(_capture(tmp_path))
    for extra, environ in (((), {}), (("--color=never",), {}), (("--color=auto",), {"NO_COLOR": "1"})):
        assert "\x1b" not in cli("read", path, *extra, environ=environ).out, extra
    assert RED in cli("read", path, "--color=always", environ={"NO_COLOR": "1"}).out
    bad = cli("read", path, "--color=sometimes")
    assert bad.status == 2 and "--color=sometimes" in bad.err


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_auto_colours_a_terminal_unless_no_color_or_dumb() -> None:
    tty, pipe = _Tty(), io.StringIO()
    assert wants_colour("auto", tty, {}) and not wants_colour("auto", pipe, {})
    assert not wants_colour("auto", tty, {"NO_COLOR": "x"}) and not wants_colour("auto", tty, {"TERM": "dumb"})
    assert wants_colour("auto", tty, {"NO_COLOR": ""})  # (no-color.org: set and not empty)
    assert wants_colour("always", pipe, {"NO_COLOR": "1"}) and not wants_colour("never", tty, {})
