"""Frames built by pymavlink (an independent implementation) for the tests."""

from __future__ import annotations

from pymavlink.dialects.v10 import common as v1
from pymavlink.dialects.v20 import all as v2


def mav2(sysid: int = 1, compid: int = 1) -> v2.MAVLink:
    return v2.MAVLink(None, srcSystem=sysid, srcComponent=compid)


def mav1(sysid: int = 1, compid: int = 1) -> v1.MAVLink:
    return v1.MAVLink(None, srcSystem=sysid, srcComponent=compid)


def heartbeat(mav: v2.MAVLink) -> bytes:
    return mav.heartbeat_encode(2, 12, 81, 0, 4, 3).pack(mav)


def command_long_rtl(mav: v2.MAVLink) -> bytes:
    return mav.command_long_encode(1, 1, 20, 0, 0, 0, 0, 0, 0, 0, 0).pack(mav)


def statustext(mav: v2.MAVLink, text: str = "hello") -> bytes:
    return mav.statustext_encode(6, text.encode()).pack(mav)
