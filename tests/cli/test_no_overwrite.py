"""No command writes over the capture it reads: a forensics tool keeps its evidence. Each output option
pointed at the capture (by another spelling of its path too) is a usage error before anything is read,
and the capture is left byte for byte as it was."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tests.conftest import CAPTURES, Cli

OPTIONS = [("read", "-w"), ("params", "--out"), ("mission", "--plan"), ("track", "--gpx"), ("track", "--kml"),
           ("track", "--geojson")]


@pytest.mark.parametrize(("command", "option"), OPTIONS)
def test_an_output_option_naming_the_capture_is_refused(cli: Cli, tmp_path: Path, command: str, option: str) -> None:
    capture = tmp_path / "flight.pcap"
    shutil.copy(CAPTURES / "ftp_params.pcap", capture)
    before = capture.read_bytes()
    for spelling in (str(capture), str(tmp_path / "." / "flight.pcap")):
        status, out, err = cli(command, str(capture), option, spelling)
        assert status == 2
        assert err == f"mavscope: {command}: {option} {spelling} is the capture being read\n"
        assert capture.read_bytes() == before


def test_plot_out_naming_the_capture_is_refused(cli: Cli, tmp_path: Path) -> None:
    capture = tmp_path / "flight.svg"  # a capture may have any name: plot's --out needs .png or .svg
    shutil.copy(CAPTURES / "px4_sitl_udp.pcap", capture)
    before = capture.read_bytes()
    status, _, err = cli("plot", str(capture), "HEARTBEAT.type", "--out", str(capture))
    assert status == 2 and "is the capture being read" in err
    assert capture.read_bytes() == before
