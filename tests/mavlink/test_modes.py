"""Flight mode names per autopilot (mavscope.mavlink.modes) against pymavlink's mavutil, an implementation
with its own hand-written tables (mode_mapping_acm, _apm, _rover, _sub, _tracker for ArduPilot by MAV_TYPE;
interpret_px4_mode for PX4's main/sub modes), where mavscope takes ArduPilot's numbers from the XML enums
and PX4's from px4_custom_mode.h."""

from __future__ import annotations

import math

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import all as pm

from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.modes import Modes, px4_mode_name
from tests.support.builders import heartbeat_msg

AP, PX4 = pm.MAV_AUTOPILOT_ARDUPILOTMEGA, pm.MAV_AUTOPILOT_PX4
CUSTOM = pm.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
# The same mode spelled differently by the XML enum and mavutil's tables (same number, same mode).
SPELLINGS = {"FLY_BY_WIRE_A": "FBWA", "FLY_BY_WIRE_B": "FBWB", "INITIALIZING": "INITIALISING",
             "LOITER_ALT_QLAND": "LOITERALTQLAND"}


# Modes mavutil names that pymavlink 2.4.50's ardupilotmega.xml does not: Copter's retired POSITION (8) and
# OF_LOITER (10) and its newer RATE_ACRO (29), Rover's retired LEARNING (2); Blimp has no enum in the XML.
XML_LACKS = {"acm": {"POSITION", "OF_LOITER", "RATE_ACRO"}, "rover": {"LEARNING"}}


def table_name(table: dict[int, str]) -> str:
    return next(n for n in ("acm", "apm", "rover", "tracker", "sub", "blimp")
                if getattr(mavutil, f"mode_mapping_{n}") is table)


@pytest.mark.parametrize("mav_type", sorted(mavutil.AP_MAV_TYPE_MODE_MAP_DEFAULT), ids=str)
def test_ardupilot_modes_agree_with_mavutil(dialect: Dialect, mav_type: int) -> None:
    modes = Modes(dialect)
    table = mavutil.AP_MAV_TYPE_MODE_MAP_DEFAULT[mav_type]
    compared = 0
    for number, theirs in table.items():
        ours = modes.name(AP, mav_type, CUSTOM, number)
        if ours.startswith("custom mode"):  # a number ardupilotmega.xml does not name
            assert theirs in XML_LACKS.get(table_name(table), {theirs}), (mav_type, number, theirs)
            continue
        assert SPELLINGS.get(ours, ours) == theirs, (mav_type, number)
        assert mavutil.mode_string_v10(heartbeat_msg(mav_type, AP, CUSTOM, number)) == theirs
        compared += 1
    assert compared >= (0 if mav_type == pm.MAV_TYPE_AIRSHIP else 6)


def test_px4_modes_agree_with_mavutil() -> None:
    # mavutil's names drop the AUTO. prefix; FOLLOWME is PX4's AUTO.FOLLOW_TARGET; sub mode 7 was RTGS
    # until PX4 deleted it in 2020 (px4_custom_mode.h: PX4_CUSTOM_SUB_MODE_AUTO_RESERVED_DO_NOT_USE), main
    # mode 8 RATTITUDE is RATTITUDE_LEGACY in PX4's header since it was retired.
    theirs_for = {"AUTO.FOLLOW_TARGET": "FOLLOWME", "AUTO.RESERVED_DO_NOT_USE": "RTGS",
                  "RATTITUDE_LEGACY": "RATTITUDE"}
    compared = 0
    for main in range(1, 9):
        for sub in range(0, 9):
            theirs = mavutil.interpret_px4_mode(0, sub << 24 | main << 16)
            if theirs == "UNKNOWN" or (main != 4 and sub):
                continue
            ours = px4_mode_name(main, sub)
            assert theirs_for.get(ours, ours.removeprefix("AUTO.")) == theirs, (main, sub)
            compared += 1
    assert compared == 7 + 7  # MANUAL..RATTITUDE (not AUTO: 7) and AUTO's sub modes 2..8


def test_mode_of_heartbeats_and_commands(dialect: Dialect) -> None:
    modes = Modes(dialect)
    assert modes.name(PX4, pm.MAV_TYPE_QUADROTOR, CUSTOM | 156, 0x0404_0000) == "AUTO.MISSION"
    assert modes.name(PX4, pm.MAV_TYPE_QUADROTOR, CUSTOM, 2 << 24 | 3 << 16) == "POSCTL.SLOW"
    assert modes.name(AP, pm.MAV_TYPE_SUBMARINE, CUSTOM, 19) == "MANUAL"
    assert modes.name(AP, pm.MAV_TYPE_GROUND_ROVER, CUSTOM, 10) == "AUTO"
    assert modes.name(AP, pm.MAV_TYPE_QUADROTOR, CUSTOM, 999) == "custom mode 999"
    # no custom mode: the MAV_MODE entry of base_mode (common.xml MAV_MODE_GUIDED_ARMED = 216)
    assert modes.name(pm.MAV_AUTOPILOT_GENERIC, pm.MAV_TYPE_QUADROTOR, 216, 0) == "GUIDED_ARMED"
    assert modes.name(pm.MAV_AUTOPILOT_GENERIC, pm.MAV_TYPE_QUADROTOR, 0x20, 0) == "base mode 0x20"
    # MAV_CMD_DO_SET_MODE: param1 base mode, param2 custom (PX4: main), param3 PX4's sub mode
    assert modes.command_mode(PX4, pm.MAV_TYPE_QUADROTOR, (1.0, 4.0, 3.0)) == "AUTO.LOITER"
    assert modes.command_mode(AP, pm.MAV_TYPE_QUADROTOR, (1.0, 9.0, 0.0)) == "LAND"  # the signed-attack capture's
    assert modes.command_mode(AP, pm.MAV_TYPE_QUADROTOR, (1.0, math.nan, 0.0)) is None
    assert modes.command_mode(AP, pm.MAV_TYPE_QUADROTOR, (1.0, 2.5, 0.0)) is None


def test_vehicles_are_told_from_ground_stations_and_peripherals(dialect: Dialect) -> None:
    modes = Modes(dialect)
    assert modes.is_vehicle(pm.MAV_TYPE_QUADROTOR, PX4)
    assert not modes.is_vehicle(pm.MAV_TYPE_GCS, pm.MAV_AUTOPILOT_INVALID)
    assert not modes.is_vehicle(pm.MAV_TYPE_CAMERA, pm.MAV_AUTOPILOT_GENERIC)  # BlueOS's camera 1/100
    assert not modes.is_vehicle(pm.MAV_TYPE_ONBOARD_CONTROLLER, pm.MAV_AUTOPILOT_INVALID)
    assert pm.MAV_TYPE_VTOL_QUADROTOR in modes.aerial and pm.MAV_TYPE_SUBMARINE not in modes.aerial
