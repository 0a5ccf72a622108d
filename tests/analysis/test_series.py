"""`mavscope plot` and its core (mavscope.analysis.series): bucket statistics against values pymavlink
reads from the same capture, bounded buckets that keep every extreme, field names, and the images."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest

from mavscope.analysis.series import MAX_BUCKETS, Series, field_getter
from mavscope.errors import UsageError
from mavscope.fields.registry import FieldRegistry
from mavscope.mavlink.dialect import Dialect
from tests.conftest import CAPTURES, Cli
from tests.support.pymavlink_reader import read_pcap

SPOOF = CAPTURES / "gps_spoof.pcap"


def test_buckets_against_pymavlink(cli: Cli) -> None:
    doc = cli.json("plot", SPOOF, "GLOBAL_POSITION_INT.relative_alt", "--interval", "2")
    msgs = read_pcap(SPOOF)
    t0 = msgs[0].time  # the capture's first frame
    want: dict[int, list[int]] = {}
    for m in msgs:
        if m.name == "GLOBAL_POSITION_INT":
            want.setdefault(int((m.time - t0) / 2), []).append(m.msg.relative_alt)
    (s,) = doc["series"]
    assert s["interval"] == 2 and s["units"] == "mm" and doc["x"] == "s"
    assert s["count"] == sum(len(v) for v in want.values())
    got = {round(b["start"] / 2): (b["count"], b["min"], b["max"], b["avg"]) for b in s["buckets"]}
    assert got == {k: (len(v), min(v), max(v), pytest.approx(sum(v) / len(v))) for k, v in want.items()}


def test_several_fields_and_a_filter(cli: Cli) -> None:
    doc = cli.json("plot", SPOOF, "GPS_RAW_INT.satellites_visible", "mavlink.seq", "-Y", "mavlink.sysid == 1")
    sats, seq = doc["series"]
    values = [m.msg.satellites_visible for m in read_pcap(SPOOF) if m.name == "GPS_RAW_INT"]
    assert (sats["count"], sats["min"], sats["max"]) == (len(values), min(values), max(values)) == (300, 3, 19)
    vehicle = [m for m in read_pcap(SPOOF) if m.src[0] == 1]
    assert seq["count"] == len(vehicle) and (seq["min"], seq["max"]) == (0, 255)


def test_bounded_buckets_keep_the_extremes() -> None:
    s = Series("x", interval=0.01)
    for i in range(200_000):
        s.add(i * 0.05, math.sin(i / 1000) + (50.0 if i == 123_457 else 0.0))
    assert len(s.buckets) <= MAX_BUCKETS and s.width >= 0.01 * 2 ** 9
    assert max(b.high for b in s.buckets if b) == s.high == pytest.approx(50 + math.sin(123.457))
    assert sum(b.count for b in s.buckets if b) == s.count == 200_000


def test_field_names(dialect: Dialect) -> None:
    reg = FieldRegistry(dialect)
    for expr, error in (("NO_SUCH.field", "no such field"), ("HEARTBEAT", "a message, not a field"),
                        ("STATUSTEXT.text", "not a number"), ("BATTERY_STATUS.voltages", "give an element"),
                        ("BATTERY_STATUS.voltages[10]", "no element 10"), ("mavlink.msgname", "not a numeric")):
        with pytest.raises(UsageError, match=error):
            field_getter(reg, expr)
    _, units = field_getter(reg, "BATTERY_STATUS.voltages[0]")
    assert units == "mV"
    _, units = field_getter(reg, "relative_alt")  # a bare name: every message with that field
    assert units == "mm"


@pytest.mark.parametrize("suffix", ["png", "svg"])
def test_images(tmp_path: Path, cli: Cli, suffix: str) -> None:
    pytest.importorskip("matplotlib", reason="the plot extra (pip install 'mavscope[plot]') is not installed")
    out = tmp_path / f"alt.{suffix}"
    status, stdout, err = cli("plot", SPOOF, "GLOBAL_POSITION_INT.relative_alt", "VFR_HUD.alt", "--out", out)
    assert status == 0, err
    assert f"wrote {out}" in stdout and "GLOBAL_POSITION_INT.relative_alt [mm]: 300 values" in stdout
    data = out.read_bytes()
    if suffix == "png":
        assert data[:8] == b"\x89PNG\r\n\x1a\n"
    else:
        assert ET.fromstring(data).tag == "{http://www.w3.org/2000/svg}svg"


def test_without_matplotlib_one_line(tmp_path: Path, cli: Cli, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib raises ImportError
    status, _, err = cli("plot", SPOOF, "GLOBAL_POSITION_INT.relative_alt", "--out", tmp_path / "x.png")
    assert status == 2 and err.count("\n") == 1 and "matplotlib" in err and "mavscope[plot]" in err


def test_terminal_chart_and_usage(cli: Cli) -> None:
    status, out, err = cli("plot", SPOOF, "GLOBAL_POSITION_INT.relative_alt", "--width", "80", "--height", "6")
    assert status == 0, err
    lines = out.splitlines()
    assert lines[0].startswith("GLOBAL_POSITION_INT.relative_alt [mm]: 300 values, min 0, max 30000")
    assert len(lines) == 1 + 6 + 1 and all(len(line) <= 80 for line in lines[1:])
    assert any(0x2800 < ord(c) <= 0x28FF for c in "".join(lines[1:7]))  # braille dots
    for argv, error in (((SPOOF,), "at least one field"), ((SPOOF, "x", "--out", "a.jpg"), ".png or .svg"),
                        ((SPOOF, "GLOBAL_POSITION_INT.lat", "--interval", "-1"), "positive")):
        status, _, err = cli("plot", *argv)
        assert status == 2 and error in err, err
    doc = json.loads(cli("plot", "-r", SPOOF, "GPS_RAW_INT.fix_type", "--json").out)
    assert doc["series"][0]["field"] == "GPS_RAW_INT.fix_type"


def test_nan_values_are_counted_not_plotted(cli: Cli) -> None:
    """px4_sitl_udp.pcap's MISSION_ITEM_INT.param4 (yaw: NaN means "keep the current heading" in PX4's
    missions), read with pymavlink: the NaNs are left out of the series and counted apart."""
    path = CAPTURES / "px4_sitl_udp.pcap"
    values = [m.msg.param4 for m in read_pcap(path) if m.name == "MISSION_ITEM_INT"]
    nans = sum(1 for v in values if math.isnan(v))
    assert nans and nans < len(values)
    (s,) = cli.json("plot", path, "MISSION_ITEM_INT.param4")["series"]
    assert (s["count"], s["not_finite"]) == (len(values) - nans, nans)
    _, out, _ = cli("plot", str(path), "MISSION_ITEM_INT.param4")
    assert f"{len(values) - nans} values ({nans} NaN or infinite left out)" in out


@pytest.mark.parametrize("values", [[1e20, 1e20, 1e20], [-1e308, 1e308], [5e-324, 5e-324], [-2.0 ** 60] * 2])
def test_terminal_chart_of_extreme_values(values: list[float]) -> None:
    """A constant too large for +-1 to widen (1e20: the span stayed 0, ZeroDivisionError), and values whose
    span overflows a float (-1e308 .. 1e308: inf / inf); the chart draws them, the extremes on its edges."""
    from mavscope.output.plotting import chart

    s = Series("x")
    for i, v in enumerate(values):
        s.add(float(i), v)
    lines = chart(s, 40, 6).plain.splitlines()
    assert len(lines) == 8 and any("\u2801" <= c <= "\u28ff" for c in "".join(lines[1:7]))  # dots drawn
