"""Frames built by pymavlink (an independent encoder) for the container tests, and lookups in a tree."""

from __future__ import annotations

from pymavlink.dialects.v10 import ardupilotmega as apm1
from pymavlink.dialects.v20 import ardupilotmega as apm2

from mavscope.fields.tree import Item, flatten, frame_items
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.mavlink.framing import Framer, build_frame


def frame_of(data: bytes, dialect: Dialect) -> Frame:
    """The one frame `data` holds, as mavscope's framer finds it."""
    found, _skipped, _end = Framer(dialect.messages).scan(data, 0, len(data), True)
    assert len(found) == 1, found
    start, end, status, crc = found[0]
    return build_frame(data, start, end, status, crc, dialect.messages, 1, 1, None, "raw", None, None, 0, (), None)


def mav(version: int = 2, sysid: int = 255, compid: int = 190) -> apm2.MAVLink:
    module = apm2 if version == 2 else apm1
    return module.MAVLink(None, srcSystem=sysid, srcComponent=compid)


def ftp_frame(dialect: Dialect, ftp_payload: bytes, version: int = 2) -> Frame:
    """A FILE_TRANSFER_PROTOCOL frame whose payload field holds `ftp_payload` (zero-filled to 251 bytes)."""
    m = mav(version)
    module = apm2 if version == 2 else apm1
    msg = module.MAVLink_file_transfer_protocol_message(0, 1, 1, list(ftp_payload.ljust(251, b"\0")[:251]))
    return frame_of(msg.pack(m), dialect)


def items_named(frame: Frame, dialect: Dialect, name: str) -> list[Item]:
    return [it for it in flatten(frame_items(frame, dialect)) if it.name == name]


def item(frame: Frame, dialect: Dialect, name: str) -> Item:
    found = items_named(frame, dialect, name)
    assert len(found) == 1, (name, [it.label for it in flatten(frame_items(frame, dialect))])
    return found[0]


def wire(frame: Frame, it: Item) -> bytes:
    """The bytes an item covers in its frame (what the hex pane highlights)."""
    return frame.raw[it.offset : it.offset + it.length]
