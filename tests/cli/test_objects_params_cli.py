"""The command lines of `objects` and `params`: bad options and nothing to write are one line on stderr
with exit status 2; a capture without objects or parameters says so."""

from __future__ import annotations

from pathlib import Path

from tests.conftest import CAPTURES, Cli
from tests.support.ftpflows import OPEN_RO, READ, Flow


def test_usage_errors(cli: Cli, tmp_path: Path) -> None:
    status, _, err = cli("objects", CAPTURES / "ftp_params.pcap", "--max-object-mb", "0")
    assert status == 2 and err.startswith("mavscope: objects: --max-object-mb") and err.count("\n") == 1
    status, _, err = cli("objects", CAPTURES / "ftp_params.pcap", "--max-holes-mb", "-1")
    assert status == 2 and err.startswith("mavscope: objects: --max-object-mb") and err.count("\n") == 1
    status, _, err = cli("params", CAPTURES / "px4_sitl_udp.pcap", "--out", tmp_path / "x.param")
    assert status == 2 and "holds no parameter values to write" in err and not (tmp_path / "x.param").exists()
    blocker = tmp_path / "file"
    blocker.write_text("")
    status, _, err = cli("objects", CAPTURES / "ftp_params.pcap", "--out", blocker / "sub")
    assert status == 2 and err.startswith("mavscope: objects: --out") and err.count("\n") == 1
    status, _, err = cli("params", CAPTURES / "ftp_params.pcap", "--diff", tmp_path / "missing.param")
    assert status == 2 and "missing.param" in err


def test_nothing_to_report(cli: Cli) -> None:
    status, out, err = cli("objects", CAPTURES / "px4_sitl_udp.pcap")
    assert status == 0 and "No object" in out, err
    doc = cli.json("params", CAPTURES / "px4_sitl_udp.pcap")
    assert (doc["final"], doc["timeline"], doc["main_component"]) == ({}, [], None)


def test_diff_against_something_without_parameters(cli: Cli, tmp_path: Path) -> None:
    """A review compared with a file of random bytes and got "0 changed, 0 only here, 0 only there":
    comparing with nothing is an error, whether the other is junk or a capture without parameters."""
    junk = tmp_path / "random.bin"
    junk.write_bytes(bytes(range(256)) * 12)
    for other in (str(junk), str(CAPTURES / "px4_sitl_udp.pcap")):
        status, out, err = cli("params", str(CAPTURES / "ftp_params.pcap"), "--diff", other)
        assert status == 2 and out == ""
        assert err.endswith(f"params: --diff {other}: no parameter values in it (neither a parameter file nor a "
                            "capture with PARAM_VALUE, PARAM_EXT_VALUE or param.pck)\n")


def test_the_holes_allowance_is_an_option(cli: Cli, tmp_path: Path) -> None:
    """One reply of 5 bytes at offset 2 MiB: a file of 2 MiB + 5 bytes by default (zeros before the data);
    with --max-holes-mb 1 the piece is not kept, and the limit says so."""
    flow = Flow()
    flow.reply(flow.request(OPEN_RO, data=b"/far"), session=0)
    flow.reply(flow.request(READ, size=5, offset=2 << 20), data=b"hello")
    tlog = flow.write(tmp_path)
    [obj] = cli.json("objects", tlog)["objects"]
    assert (obj["size"], obj["dropped_bytes"], obj["gaps"]) == ((2 << 20) + 5, 0, [[0, 2 << 20]])
    doc = cli.json("objects", tlog, "--max-holes-mb", "1")
    [obj] = doc["objects"]
    assert (obj["size"], obj["dropped_bytes"]) == (0, 5)
    assert any("1,048,576 bytes of holes" in k for k in doc["limits"]["given_up"])
