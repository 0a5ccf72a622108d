"""Fixed values every capture shares: the capture clock, the signing key, the vehicle's home, the
endpoints' ids and addresses, link types, and the MAVLink enum values the sessions use. One place, so
that README.md and expected.json can quote exactly what the captures were built with."""

from __future__ import annotations

import hashlib
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
DEFAULT_OUTDIR = REPO / "captures"

BASE_TIME_US = 1_773_482_400 * 1_000_000  # 2026-03-14T10:00:00Z
SIGNING_EPOCH_US = 1_420_070_400 * 1_000_000  # 2015-01-01T00:00:00Z: MAVLink signing timestamps
VEHICLE_BOOT_OFFSET_MS = 41_317  # the vehicle booted this long before the capture starts
VEHICLE_UTC_OFFSET_US = 2_150  # the vehicle's UTC clock (SYSTEM_TIME, GPS) runs this much ahead

SIGNING_PASSPHRASE = "mavscope-demo"
SIGNING_KEY = hashlib.sha256(SIGNING_PASSPHRASE.encode()).digest()  # as MAVProxy derives keys
VEHICLE_LINK_ID = 0
GCS_LINK_ID = 1

# PX4 SITL default home (Zurich) and the metres-per-degree factors around it.
HOME_LAT_DEG = 47.3977419
HOME_LON_DEG = 8.5455938
HOME_ALT_M = 488.0
M_PER_DEG_LAT = 111_320.0
M_PER_DEG_LON = 111_320.0 * 0.6769049796852641  # cos(47.3977419 deg), written out: no libm at run time
DEG_TO_RAD = 0.017453292519943295

VEHICLE_SYSID, VEHICLE_COMPID = 1, 1
GCS_SYSID, GCS_COMPID = 255, 190
LOOPBACK_V4 = "127.0.0.1"
VEHICLE_UDP_PORT, GCS_UDP_PORT = 14580, 14550
ARDUPILOT_TCP_PORT, GCS_TCP_PORT = 5760, 40412
ZERO_MAC = "00:00:00:00:00:00"  # Linux loopback as tcpdump -i lo records it
SYN_WINDOW = {"S": 65_495, "SA": 65_483}  # Linux on lo; later segments: 512 << 7 (window scale)

LINKTYPE_ETHERNET = 1
LINKTYPE_LINUX_SLL2 = 276
SNAPLEN = 262_144

UNKNOWN_MSGID = 65_000  # in no pymavlink 2.4.50 dialect (60000 is STorM32's, and so in all.xml)
UNKNOWN_INCOMPAT_FLAG = 0x02  # not SIGNED (0x01), not the SecureMAV cipher bits (0xE0)

# MAVLink enum values used below (common.xml / minimal.xml).
MAV_TYPE_QUADROTOR, MAV_TYPE_GCS = 2, 6
MAV_AUTOPILOT_ARDUPILOTMEGA, MAV_AUTOPILOT_INVALID, MAV_AUTOPILOT_PX4 = 3, 8, 12
MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, MAV_MODE_FLAG_SAFETY_ARMED = 1, 128
MAV_MODE_FLAG_STABILIZE_ENABLED, MAV_MODE_FLAG_GUIDED_ENABLED, MAV_MODE_FLAG_AUTO_ENABLED = 16, 8, 4
MAV_MODE_FLAG_MANUAL_INPUT_ENABLED = 64
MAV_STATE_STANDBY, MAV_STATE_ACTIVE = 3, 4
MAV_FRAME_GLOBAL_RELATIVE_ALT_INT = 6
MAV_CMD_NAV_WAYPOINT, MAV_CMD_NAV_RETURN_TO_LAUNCH, MAV_CMD_NAV_TAKEOFF = 16, 20, 22
MAV_CMD_DO_REPOSITION, MAV_CMD_COMPONENT_ARM_DISARM = 192, 400
MAV_RESULT_ACCEPTED, MAV_MISSION_ACCEPTED, MAV_MISSION_TYPE_MISSION = 0, 0, 0
MAV_SEVERITY_WARNING, MAV_SEVERITY_INFO = 4, 6
GPS_FIX_TYPE_3D_FIX = 3
NAN = float("nan")  # PX4/QGC send NaN for "unchanged" (yaw); packs to 00 00 c0 7f on every platform

# PX4 custom_mode = sub_mode << 24 | main_mode << 16; ArduCopter custom_mode = mode number.
PX4_MODES = {"HOLD": 0x0304_0000, "MISSION": 0x0404_0000, "RTL": 0x0504_0000}
ARDUCOPTER_MODES = {"HOLD": 5, "MISSION": 3, "RTL": 6}  # LOITER, AUTO, RTL
SENSORS_PRESENT = 0x3520_FC2F  # gyro, accel, mag, baro, GPS, ... as PX4 reports them
