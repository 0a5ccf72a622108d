"""The record type every capture reader yields, and the link-type numbers they use.

Records are NamedTuples rather than frozen dataclasses: a 1M-record capture builds one per record on
the hot path and a tuple is built about three times faster (see docs/performance.md).
"""

from __future__ import annotations

from typing import NamedTuple

from mavscope.notes import Note

# pcap LINKTYPE_* values (https://www.tcpdump.org/linktypes.html) that the transport layer decodes.
LINKTYPE_NULL = 0  # BSD loopback: 4-byte address family in host byte order
LINKTYPE_ETHERNET = 1
LINKTYPE_RAW = 101  # raw IPv4 or IPv6
LINKTYPE_IEEE802_11 = 105  # 802.11 frames (a monitor-mode capture without a radio header)
LINKTYPE_LOOP = 108  # OpenBSD loopback: 4-byte address family in network byte order
LINKTYPE_IEEE802_11_RADIOTAP = 127  # 802.11 frames behind a radiotap header (monitor mode)
LINKTYPE_LINUX_SLL = 113
LINKTYPE_IPV4 = 228
LINKTYPE_IPV6 = 229
LINKTYPE_LINUX_SLL2 = 276

# Pseudo link types for inputs that carry MAVLink bytes directly (negative: never valid in a pcap).
LINKTYPE_MAVLINK_TLOG = -1  # one record = one MAVLink frame, time from the tlog's timestamp
LINKTYPE_MAVLINK_RAW = -2  # one record = a chunk of a raw byte stream; frames may span records


class Record(NamedTuple):
    """One capture record: a packet from pcap/pcapng, an entry of a tlog, or a chunk of a raw stream."""

    number: int  # 1-based position in the capture
    # Seconds since the Unix epoch as the file states it; None where the input has no timestamp. Always finite,
    # but not always a real time: a pcap gives 0 .. 2**32 + 4295 s, a pcapng anything in about -9.3e18 ..
    # 2.8e19 s (if_tsoffset, if_tsresol and 64-bit timestamps as the file sets them: negative, or past the
    # year 9999 that datetime holds), a tlog 2000 .. 2100. Readers never raise or note such a time; the
    # writers clamp it to their format (PcapWriter.clamped) and whoever formats it must cope.
    time: float | None
    linktype: int  # LINKTYPE_* above (or any other pcap link type, which the transport layer notes)
    data: bytes  # the captured bytes
    offset: int  # file offset of data[0]
    orig_len: int  # length on the wire (>= len(data) when the capture was snapped)
    notes: tuple[Note, ...] = ()  # what the reader had to say about this record (truncation, skipped garbage)
