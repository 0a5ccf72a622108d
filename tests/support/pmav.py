"""Frames built by pymavlink (an independent implementation) for the tests: names for the builders of
tests/support/builders.py (`heartbeat` is a quadrotor's, MAV_TYPE_QUADROTOR with MAV_AUTOPILOT_PX4)."""

from __future__ import annotations

from pymavlink.dialects.v20 import all as v2

from tests.support.builders import command_long
from tests.support.builders import heartbeat as heartbeat
from tests.support.builders import mav1 as mav1
from tests.support.builders import mav2 as mav2
from tests.support.builders import statustext as statustext


def command_long_rtl(mav: v2.MAVLink) -> bytes:
    return command_long(mav, 20)  # MAV_CMD_NAV_RETURN_TO_LAUNCH to 1/1
