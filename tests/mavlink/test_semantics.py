"""Value semantics written once (mavscope.mavlink.semantics) checked against the XML itself, parsed here
by pymavlink's own parser (not mavscope's dialect loader)."""

from __future__ import annotations

import math
from pathlib import Path

import pymavlink
import pytest
from pymavlink.generator import mavparse

from mavscope.mavlink import semantics
from mavscope.mavlink.dialect import Dialect

COMMON = Path(pymavlink.__file__).parent / "dialects" / "v20" / "common.xml"


@pytest.fixture(scope="module")
def mav_frame() -> dict[str, int]:
    xml = mavparse.MAVXML(str(COMMON), mavparse.PROTOCOL_2_0)
    enum = next(e for e in xml.enum if e.name == "MAV_FRAME")
    return {entry.name: entry.value for entry in enum.entry}


def test_global_frames_are_the_mav_frame_global_entries(mav_frame: dict[str, int]) -> None:
    """x/y are latitude/longitude in exactly the frames common.xml names MAV_FRAME_GLOBAL*."""
    assert semantics.GLOBAL_FRAMES == {v for k, v in mav_frame.items() if k.startswith("MAV_FRAME_GLOBAL")}
    assert semantics.MAV_FRAME_MISSION == mav_frame["MAV_FRAME_MISSION"]


def test_int_coordinates_by_frame(mav_frame: dict[str, int]) -> None:
    """MISSION_ITEM_INT x/y (common.xml): degE7 in a global frame, metres * 1e4 in a local one, and in
    MAV_FRAME_MISSION the plain param5/param6."""
    assert semantics.int_coordinate(473977419, mav_frame["MAV_FRAME_GLOBAL_RELATIVE_ALT_INT"]) == 47.3977419
    assert semantics.int_coordinate(12345, mav_frame["MAV_FRAME_LOCAL_NED"]) == 1.2345
    assert semantics.int_coordinate(7, mav_frame["MAV_FRAME_MISSION"]) == 7.0
    assert [semantics.coordinate_unit(mav_frame[n]) for n in ("MAV_FRAME_GLOBAL_INT", "MAV_FRAME_MISSION",
                                                               "MAV_FRAME_LOCAL_NED")] == ["deg", "raw", "m"]


def test_a_command_parameter_that_is_not_finite_has_no_name(dialect: Dialect) -> None:
    """int() of an infinity raises OverflowError: a COMMAND_LONG with param1 = inf crashed every summary
    line of the pure path (found by the native summary's differential tests)."""
    for value in (math.inf, -math.inf, math.nan):
        assert semantics.command_param_name(dialect, 400, 1, value) is None  # COMPONENT_ARM_DISARM: MAV_BOOL
    assert semantics.command_param_name(dialect, 400, 1, 1.0) is not None
