"""The byte arrays whose valid length another field gives, and ENCAPSULATED_DATA's chunks.

- LOG_DATA.data: `count` of its 90 bytes are log data (`log.data`).
- TUNNEL.payload: `payload_length` of its 128 bytes are the payload (`tunnel.payload`); what they hold
  is TUNNEL.payload_type (MAV_TUNNEL_PAYLOAD_TYPE), an ordinary enum field.
- SERIAL_CONTROL.data: `count` of its 70 bytes (`serial.data`), usually console text (`serial.text`).
- ENCAPSULATED_DATA.data: one 253-byte chunk (number `seqnr`) of the transfer the last
  DATA_TRANSMISSION_HANDSHAKE announced (image type, size, packets, bytes per packet). Which of its bytes
  count and where it goes in the image only that handshake says, so per frame `encap.data` is the chunk
  as sent; putting the image together is a transfer-level job, not a field's.

A count larger than the array is shown and marked malformed (`*.malformed`); the data is cut to the array.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

from mavscope.fields.containers.base import (
    BYTES,
    STR,
    Get,
    Node,
    Region,
    Spec,
    Where,
    byte_field,
    hex_text,
    memo,
    message,
    plural,
    text,
    trimmed,
)
from mavscope.mavlink.dialect import FieldDef
from mavscope.mavlink.frame import Frame


class Valid(NamedTuple):
    """An array and how many of its bytes are valid."""

    region: Region
    field: FieldDef
    declared: int  # what the count field says (may exceed the array: malformed)
    count_name: str  # the count field

    @property
    def data(self) -> bytes:
        return self.region.data[: min(self.declared, self.field.size)]

    @property
    def problem(self) -> str | None:
        if self.declared <= self.field.size:
            return None
        return (f"{self.field.message}.{self.field.name}: {self.count_name} {self.declared} exceeds its "
                f"{self.field.size} bytes")


def _valid(msg_name: str, array: str, count: str | None) -> Callable[[Frame], Valid | None]:
    """How to find the valid bytes of `msg_name.array` (`count` names the count field; None: all valid)."""
    @memo
    def get(frame: Frame) -> Valid | None:
        msg = message(frame, msg_name)
        if msg is None:
            return None
        fd = byte_field(msg.md, array)
        if fd is None:
            return None
        return Valid(msg.region(frame, fd), fd, fd.size if count is None else msg.uint(count), count or "")
    return get


LOG = _valid("LOG_DATA", "data", "count")
TUNNEL = _valid("TUNNEL", "payload", "payload_length")
SERIAL = _valid("SERIAL_CONTROL", "data", "count")
ENCAP = _valid("ENCAPSULATED_DATA", "data", None)


def _data(find: Callable[[Frame], Valid | None]) -> Get:
    def get(frame: Frame) -> object:
        v = find(frame)
        return None if v is None or not v.data else v.data
    return get


def _span(find: Callable[[Frame], Valid | None]) -> Where:
    def span(frame: Frame) -> tuple[int, int] | None:
        v = find(frame)
        return None if v is None or not v.data else v.region.span(0, len(v.data))
    return span


def _problem(find: Callable[[Frame], Valid | None]) -> Get:
    def get(frame: Frame) -> object:
        v = find(frame)
        return None if v is None else v.problem
    return get


def _serial_text(frame: Frame) -> object:
    v = SERIAL(frame)
    return None if v is None or not v.data else text(v.data)[0]


SPECS: tuple[Spec, ...] = (
    Spec("log.data", "Data", BYTES, _data(LOG), _span(LOG),
         description="LOG_DATA: the `count` valid bytes of data (absent when count is 0)"),
    Spec("log.malformed", "Malformed", STR, _problem(LOG), description="LOG_DATA: count exceeds the 90 bytes"),
    Spec("tunnel.payload", "Payload", BYTES, _data(TUNNEL), _span(TUNNEL),
         description="TUNNEL: the `payload_length` valid bytes of payload (its kind: TUNNEL.payload_type)"),
    Spec("tunnel.malformed", "Malformed", STR, _problem(TUNNEL),
         description="TUNNEL: payload_length exceeds the 128 bytes"),
    Spec("serial.data", "Data", BYTES, _data(SERIAL), _span(SERIAL),
         description="SERIAL_CONTROL: the `count` valid bytes of data"),
    Spec("serial.text", "Text", STR, _serial_text, _span(SERIAL),
         description="SERIAL_CONTROL: the valid bytes as text (UTF-8, undecodable bytes escaped)"),
    Spec("serial.malformed", "Malformed", STR, _problem(SERIAL),
         description="SERIAL_CONTROL: count exceeds the 70 bytes"),
    Spec("encap.data", "Chunk", BYTES, _data(ENCAP), _span(ENCAP),
         description="ENCAPSULATED_DATA: the chunk's 253 bytes (its number: ENCAPSULATED_DATA.seqnr)"),
)
LABELS = {s.name: s.label for s in SPECS}


def _valid_nodes(v: Valid, prefix: str, data_name: str) -> tuple[str, list[Node]]:
    data = v.data
    off, length = v.region.span(0, len(data))
    label = f"{LABELS[data_name]} ({plural(len(data))}): {hex_text(data)}{trimmed(length, len(data))}"
    nodes = [Node(label, data_name, off, length, data)]
    summary = f"{len(data)} of {v.field.size} bytes valid"
    if v.problem is not None:
        nodes.append(Node(f"[Malformed: {v.problem}]", f"{prefix}.malformed", v.region.base, 0, v.problem, (),
                          True))
        summary += " [malformed]"
    return summary, nodes


def log_subtree(frame: Frame) -> tuple[str, tuple[Node, ...]] | None:
    v = LOG(frame)
    if v is None:
        return None
    summary, nodes = _valid_nodes(v, "log", "log.data")
    return summary, tuple(nodes)


def tunnel_subtree(frame: Frame) -> tuple[str, tuple[Node, ...]] | None:
    v = TUNNEL(frame)
    if v is None:
        return None
    summary, nodes = _valid_nodes(v, "tunnel", "tunnel.payload")
    return summary, tuple(nodes)


def serial_subtree(frame: Frame) -> tuple[str, tuple[Node, ...]] | None:
    v = SERIAL(frame)
    if v is None:
        return None
    summary, nodes = _valid_nodes(v, "serial", "serial.data")
    if v.data:
        shown, ok = text(v.data)
        off, length = v.region.span(0, len(v.data))
        note = "" if ok else " [not UTF-8: undecodable bytes escaped]"
        nodes.insert(1, Node(f"{LABELS['serial.text']}: {shown!r}{note}", "serial.text", off, length, shown))
    return summary, tuple(nodes)


def encap_subtree(frame: Frame) -> tuple[str, tuple[Node, ...]] | None:
    v = ENCAP(frame)
    if v is None:
        return None
    data = v.data
    off, length = v.region.span(0, len(data))
    label = f"{LABELS['encap.data']} ({plural(len(data))}): {hex_text(data)}{trimmed(length, len(data))}"
    # Where the chunk goes and how many of its bytes count: the transfer's DATA_TRANSMISSION_HANDSHAKE.
    return "image chunk (size, type and packets: the transfer's DATA_TRANSMISSION_HANDSHAKE)", (
        Node(label, "encap.data", off, length, data),)
