"""What the transport layer hands to the MAVLink framer."""

from __future__ import annotations

from collections.abc import Hashable
from typing import NamedTuple

from mavscope.endpoint import Endpoint
from mavscope.notes import Note

TRANSPORT_UDP = "udp"
TRANSPORT_TCP = "tcp"
TRANSPORT_TLOG = "tlog"
TRANSPORT_RAW = "raw"


class Payload(NamedTuple):
    """Bytes that may hold MAVLink, with where they came from.

    Datagram payloads (UDP, one tlog entry) have `stream` None: the framer's frames never continue past
    them (a receiver's parser may: mavscope.mavlink.receivers).
    Stream payloads (TCP in one direction, a raw byte stream) carry a hashable `stream` key; the bytes
    are the next in-order bytes of that stream, and a frame may continue in the next Payload of the
    same stream.
    """

    transport: str  # TRANSPORT_*
    src: Endpoint | None  # None for a tlog entry or a raw stream
    dst: Endpoint | None
    data: bytes
    stream: Hashable | None
    record: int  # number of the Record these bytes arrived in
    offset: int | None  # file offset of data[0] where the bytes are contiguous in the file, else None
    notes: tuple[Note, ...] = ()  # anomalies the transport layer found (gaps, malformed headers)
    # a datagram reassembled from IP fragments: the records of its fragments, in record order (a frame in
    # it is shown with them all: `read -w` writes them, and the written capture reassembles it too)
    span: tuple[int, ...] | None = None
    # stream bytes that became readable in order at an earlier record than the one delivering them (the
    # capture missed a segment before them, and reassembly gave the hole up later): that (record, time); a
    # frame they complete is that record's. None: the record delivering them (`record`, or the one that
    # filled the hole before them)
    ready: tuple[int, float | None] | None = None
