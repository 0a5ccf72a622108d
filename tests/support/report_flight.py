"""A small flight built with pymavlink for the report tests: what it holds is written here, and each test's
expected values come from this construction (by hand), never from mavscope.

A GCS 255/190 and an ArduPilot quadrotor 1/1 (MAV_TYPE_QUADROTOR 2, MAV_AUTOPILOT_ARDUPILOTMEGA 3) in a
tlog, 10 ms apart (tests/support/ftpflows.Flow): HEARTBEATs of both; the vehicle's AUTOPILOT_VERSION
(flight_sw_version 4.5.6, release type 255); the GCS arms it (COMMAND_LONG 400, param1 1) and the vehicle
ACKs it (MAV_RESULT_ACCEPTED); the GCS sets a parameter (PARAM_SET ARMING_CHECK = 0) and the vehicle
confirms it (PARAM_VALUE with that value); a mission upload of 2 items (MISSION_COUNT 2, two
MISSION_REQUEST_INT / MISSION_ITEM_INT, MISSION_ACK accepted), a fence of 4 inclusion vertices (`FENCE`) and
one rally point uploaded alike, then MISSION_ITEM_REACHED 1; positions
(GLOBAL_POSITION_INT at relative altitudes of 10 and 20 m, VFR_HUD ground speed 3.5 and 7 m/s, SYS_STATUS
12.6 V and 12.1 V, GPS_RAW_INT fix 3 with 9 satellites); a STATUSTEXT `TEXT`; the GCS reads a file over
MAVLink FTP (`FILE_PATH`, `FILE_DATA`).
"""

from __future__ import annotations

from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as v2

from tests.support.builders import heartbeat_msg
from tests.support.flows import command_long
from tests.support.ftpflows import GCS, VEHICLE, Flow, read_file

TEXT = "PreArm: all good"
FILE_PATH = "/APM/logs/00000001.BIN"
FILE_DATA = bytes(range(256)) * 3
PARAM = b"ARMING_CHECK"
FLIGHT_SW = (4 << 24) | (5 << 16) | (6 << 8) | 255
LAT, LON = 473_977_420, 85_455_940


FENCE = ((-2000, -2000), (-2000, 3000), (3000, 3000), (3000, -2000))  # vertices around the mission, in 1e-7 deg


def upload(flow: Flow, mission_type: int, items: list[tuple[int, float, int, int]]) -> None:
    """An accepted upload of `items` (command, param1, lat, lon: MAV_FRAME_GLOBAL_INT) of `mission_type`."""
    flow.send(GCS, v2.MAVLink_mission_count_message(1, 1, len(items), mission_type))
    for seq, (command, p1, lat, lon) in enumerate(items):
        flow.send(VEHICLE, v2.MAVLink_mission_request_int_message(255, 190, seq, mission_type))
        flow.send(GCS, v2.MAVLink_mission_item_int_message(1, 1, seq, 5, command, 0, 1, p1, 0, 0, 0, lat, lon, 0.0,
                                                           mission_type))
    flow.send(VEHICLE, v2.MAVLink_mission_ack_message(255, 190, 0, mission_type))


def flight() -> Flow:
    flow = Flow()
    flow.send(VEHICLE, heartbeat_msg(2, 3, 1, 0, 3))  # disarmed, MAV_STATE_STANDBY
    flow.send(GCS, heartbeat_msg(6, 8))
    flow.send(VEHICLE, v2.MAVLink_autopilot_version_message(0, FLIGHT_SW, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0, 0, 0))
    flow.send(GCS, command_long(400, 1.0))
    flow.send(VEHICLE, v2.MAVLink_command_ack_message(400, 0))
    flow.send(GCS, v2.MAVLink_param_set_message(1, 1, PARAM, 0.0, 6))
    flow.send(VEHICLE, v2.MAVLink_param_value_message(PARAM, 0.0, 6, 1, 0))
    flow.send(GCS, v2.MAVLink_mission_count_message(1, 1, 2))
    for seq in (0, 1):
        flow.send(VEHICLE, v2.MAVLink_mission_request_int_message(255, 190, seq))
        flow.send(GCS, v2.MAVLink_mission_item_int_message(1, 1, seq, 6, 16, 0, 1, 0, 0, 0, 0,
                                                           LAT + seq * 1000, LON + seq * 1000, 30.0))
    flow.send(VEHICLE, v2.MAVLink_mission_ack_message(255, 190, 0))
    upload(flow, 1, [(5001, 4.0, LAT + dy, LON + dx) for dy, dx in FENCE])  # MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
    upload(flow, 2, [(5100, 0.0, LAT + 500, LON - 500)])  # MAV_CMD_NAV_RALLY_POINT
    flow.send(VEHICLE, v2.MAVLink_mission_item_reached_message(1))
    for alt_mm, speed, mv in ((10_000, 3.5, 12_600), (20_000, 7.0, 12_100)):
        flow.send(VEHICLE, v2.MAVLink_global_position_int_message(1000, LAT, LON + alt_mm, 500_000, alt_mm,
                                                                   0, 0, 0, 0))
        flow.send(VEHICLE, v2.MAVLink_vfr_hud_message(0.0, speed, 0, 0, 0.0, 0.0))
        flow.send(VEHICLE, v2.MAVLink_sys_status_message(0, 0, 0, 0, mv, -1, -1, 0, 0, 0, 0, 0, 0))
        flow.send(VEHICLE, v2.MAVLink_gps_raw_int_message(0, 3, LAT, LON, 500_000, 0, 0, 0, 0, 9))
    flow.send(VEHICLE, v2.MAVLink_statustext_message(6, TEXT.encode()))
    read_file(flow, FILE_PATH, FILE_DATA)
    flow.send(VEHICLE, heartbeat_msg(2, 3, 1, 0, 3))
    return flow


def write(tmp: Path, name: str = "flight.tlog") -> tuple[Path, Flow]:
    f = flight()
    return f.write(tmp, name), f
