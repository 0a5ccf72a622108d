"""Scaled fields in filters: the display-unit companions, the warning, and "did you mean" for enum names.

Frames built with pymavlink (a tlog): GLOBAL_POSITION_INT of 1/1 at 40.07° N (lat 400700000 in degE7),
alt 12345 mm, vx 150 cm/s, hdg 9000 cdeg; the same at 40.06° N. The expected values are the numbers put in
divided by the scale the XML's `units` names (degE7: 10**7, mm: 1000, cm/s: 100, cdeg: 100), by hand.
"""

from __future__ import annotations

from pathlib import Path

from tests.conftest import Cli
from tests.support.builders import heartbeat, mav2, timed, write_tlog


def _capture(tmp: Path) -> str:
    def gpi(seq: int, lat: int) -> bytes:
        mav = mav2(1, 1, seq)
        return bytes(mav.global_position_int_encode(1000 * seq, lat, 85455938, 500000, 12345, 150, 0, 0, 9000)
                     .pack(mav))

    return write_tlog(tmp, timed([heartbeat(mav2(1, 1, 0)), gpi(1, 400700000), gpi(2, 400600000)], 1_700_000_000.0))


def _frames(cli: Cli, path: str, flt: str) -> tuple[list[str], str]:
    got = cli("read", path, "-Y", flt, "-T", "fields", "-e", "frame.number")
    assert got.status == 0, got.err
    return got.out.splitlines(), got.err


def test_companions_compare_in_the_display_unit(cli: Cli, tmp_path: Path) -> None:
    path = _capture(tmp_path)
    for flt, want in (("GLOBAL_POSITION_INT.lat_deg > 40.065", ["2"]), ("lat_deg < 40.065", ["3"]),
                      ("GLOBAL_POSITION_INT.alt_m == 500", ["2", "3"]), ("relative_alt_m == 12.345", ["2", "3"]),
                      ("vx_mps == 1.5", ["2", "3"]), ("GLOBAL_POSITION_INT.hdg_deg in {90 180}", ["2", "3"]),
                      ("lat_deg", ["2", "3"])):
        frames, err = _frames(cli, path, flt)
        assert frames == want and err == "", (flt, frames, err)
    got = cli("read", path, "-T", "fields", "-e", "lat", "-e", "lat_deg", "-e", "alt_m", "-e", "vx_mps",
              "-e", "hdg_deg", "-Y", "GLOBAL_POSITION_INT")
    assert got.out.splitlines() == ["400700000\t40.07\t500.0\t1.5\t90.0", "400600000\t40.06\t500.0\t1.5\t90.0"]


def test_a_display_unit_number_against_the_raw_field_warns(cli: Cli, tmp_path: Path) -> None:
    path = _capture(tmp_path)
    frames, err = _frames(cli, path, "GLOBAL_POSITION_INT.lat > 40.07")
    assert frames == ["2", "3"]  # still compared as sent (every latitude north of 0.000004 degrees)
    assert err.count("\n") == 1 and "GLOBAL_POSITION_INT.lat is sent in degE7 (1e-7 degrees)" in err
    assert "GLOBAL_POSITION_INT.lat_deg > 40.07" in err and "GLOBAL_POSITION_INT.lat > 400700000" in err
    _, err = _frames(cli, path, "vx == 1.5")
    assert "vx is sent in cm/s" in err and "vx_mps == 1.5" in err and "vx == 150" in err
    for quiet in ("GLOBAL_POSITION_INT.lat > 400000000", "lat == 0", "alt > 1000", "GLOBAL_POSITION_INT.lat_deg > 40"):
        assert _frames(cli, path, quiet)[1] == "", quiet


def test_misspelt_enum_names_get_a_suggestion(cli: Cli, tmp_path: Path) -> None:
    path = _capture(tmp_path)
    for flt, want in (("HEARTBEAT.type == MAV_TYPE_QUADROTR", "MAV_TYPE_QUADROTOR"),
                      ("HEARTBEAT.autopilot == MAV_AUTOPILOT_ARDUPILOTMEG", "MAV_AUTOPILOT_ARDUPILOTMEGA")):
        got = cli("read", path, "-Y", flt)
        assert got.status == 2 and f'did you mean "{want}"?' in got.err, got.err
