"""Which parameters guard the vehicle, and which values turn a guard off.

Names as ArduPilot and PX4 define them (their parameter references): MAVLink access (ArduPilot's
SYSID_ENFORCE/SYSID_MYGCS and, since 4.7, MAV_GCS_SYSID/MAV_OPTIONS, and the per-link MAVn_OPTIONS whose
bit 0 accepts unsigned MAVLink 2 frames), failsafes (ArduPilot FS_*, BATT*_FS_*, THR_FAILSAFE, AFS_*;
PX4 NAV_DLL_ACT, NAV_RCL_ACT, COM_*_ACT, COM_DL_LOSS_T, COM_RC_LOSS_T), fences (ArduPilot FENCE_*, PX4
GF_*), arming checks (ArduPilot ARMING_*, PX4 COM_ARM_*, CBRK_*: PX4's circuit breakers, which switch
checks off when set to their magic number) and scripting (ArduPilot SCR_*: Lua scripts run on the
vehicle). PX4 keeps its signing key on the SD card (SETUP_SIGNING), not in a parameter.
"""

from __future__ import annotations

import re
from collections.abc import Callable

from mavscope.analysis.params.values import Value

CATEGORIES: tuple[tuple[str, re.Pattern[str]], ...] = (
    ("signing and access", re.compile(r"^(SYSID_ENFORCE|SYSID_MYGCS|MAV_GCS_SYSID|MAV_OPTIONS|MAV\d+_OPTIONS"
                                      r"|SERIAL\d+_PROTOCOL|BRD_OPTIONS)$")),
    ("failsafe", re.compile(r"^(FS_\w+|BATT\d*_FS_\w+|THR_FAILSAFE|THR_FS_VALUE|AFS_\w+|RC_FS_\w+|NAV_DLL_ACT"
                            r"|NAV_RCL_ACT|COM_\w+_ACT|COM_DL_LOSS_T|COM_RC_LOSS_T|COM_RCL_EXCEPT|COM_DLL_EXCEPT"
                            r"|GCS_PID_MASK)$")),
    ("fence", re.compile(r"^(FENCE_\w+|GF_\w+)$")),
    ("arming checks", re.compile(r"^(ARMING_\w+|COM_ARM_\w+|CBRK_\w+)$")),
    ("scripting", re.compile(r"^SCR_\w+$")),
)


def _zero(v: Value) -> bool:
    return not isinstance(v, str) and v == 0


def _nonzero(v: Value) -> bool:
    return not isinstance(v, str) and v != 0


def _bit0(v: Value) -> bool:
    return isinstance(v, (int, float)) and int(v) & 1 == 1


# name pattern -> (the value turns the protection off?, what it turns off)
DISABLES: tuple[tuple[re.Pattern[str], Callable[[Value], bool], str], ...] = (
    (re.compile(r"^ARMING_CHECK$"), _zero, "every pre-arm check"),
    (re.compile(r"^ARMING_REQUIRE$"), _zero, "the arming requirement (outputs live while disarmed)"),
    (re.compile(r"^FENCE_ENABLE$"), _zero, "the geofence"),
    (re.compile(r"^(FENCE_ACTION|GF_ACTION)$"), _zero, "the fence breach action"),
    (re.compile(r"^(FS_GCS_ENABLE|FS_THR_ENABLE|THR_FAILSAFE|FS_EKF_ACTION|FS_CRASH_CHECK)$"), _zero, "a failsafe"),
    (re.compile(r"^BATT\d*_FS_(LOW|CRT)_ACT$"), _zero, "a battery failsafe"),
    (re.compile(r"^(NAV_DLL_ACT|NAV_RCL_ACT|COM_LOW_BAT_ACT)$"), _zero, "a failsafe action"),
    (re.compile(r"^SYSID_ENFORCE$"), _zero, "the check of the GCS system id"),
    (re.compile(r"^MAV\d+_OPTIONS$"), _bit0, "signature checking: the link accepts unsigned MAVLink 2 frames"),
    (re.compile(r"^CBRK_\w+$"), _nonzero, "a check (a PX4 circuit breaker is engaged)"),
)


def category(name: str) -> str | None:
    """The security category of a parameter name, or None."""
    for cat, pattern in CATEGORIES:
        if pattern.match(name):
            return cat
    return None


def disables(name: str, value: Value) -> str | None:
    """What setting `name` to `value` turns off, or None."""
    for pattern, test, what in DISABLES:
        if pattern.match(name) and test(value):
            return what
    return None
