"""`read -w OUT`: write the capture records that hold the frames shown.

Packet captures (pcap, pcapng) are copied record for record with their link types and times: a
`.pcapng` output keeps every link type; a pcap output takes one link type (a capture mixing several
must be written as `.pcapng`). Inputs without a link layer (tlog, raw) have no packets to copy: each
shown frame is wrapped in a synthesised Ethernet/IPv4/UDP packet 127.0.0.1:14550 -> 127.0.0.1:14550,
so Wireshark's MAVLink dissector decodes the file. A `.tlog` output writes tlog entries instead.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Iterable
from pathlib import Path

from mavscope.capture.base import LINKTYPE_ETHERNET, Record
from mavscope.capture.detect import open_capture
from mavscope.capture.writer import PcapngWriter, PcapWriter, synth_udp_ipv4
from mavscope.errors import UsageError
from mavscope.mavlink.frame import Frame

SYNTH_SRC = "127.0.0.1:14550"
SYNTH_DST = "127.0.0.1:14550"
_TLOG_TIME = struct.Struct(">Q")


def _output_kind(out: str | os.PathLike[str]) -> str:
    suffix = Path(out).suffix.lower()
    return {".pcapng": "pcapng", ".tlog": "tlog"}.get(suffix, "pcap")


def write_records(source: str | os.PathLike[str], out: str | os.PathLike[str], records: set[int]) -> int:
    """Copy the records numbered in `records` from the packet capture `source` to `out`; their count."""
    kind = _output_kind(out)
    if kind == "tlog":
        raise UsageError("-w: a packet capture can be written as .pcap or .pcapng, not .tlog")
    with open_capture(source) as reader:
        chosen: Iterable[Record] = (r for r in reader if r.number in records and r.linktype >= 0)
        if kind == "pcapng":
            with PcapngWriter(out) as w:
                n = 0
                for rec in chosen:
                    w.write(rec.time, rec.data, rec.orig_len, linktype=rec.linktype)
                    n += 1
                return n
        writer: PcapWriter | None = None
        n = 0
        try:
            for rec in chosen:
                if writer is None:
                    writer = PcapWriter(out, rec.linktype)
                elif rec.linktype != writer.linktype:
                    raise UsageError(f"-w: the frames shown come from several link types; write them as "
                                     f"{Path(out).with_suffix('.pcapng').name}")
                writer.write(rec.time, rec.data, rec.orig_len)
                n += 1
            if writer is None:
                writer = PcapWriter(out, LINKTYPE_ETHERNET)
        finally:
            if writer is not None:
                writer.close()
        return n


class FrameWriter:
    """Writes shown frames of a tlog or raw input to a pcap, pcapng or tlog file as they come."""

    def __init__(self, out: str | os.PathLike[str]) -> None:
        self.kind = _output_kind(out)
        if self.kind == "tlog":
            self._f = open(out, "wb")  # noqa: SIM115 - closed in close()
            self._w: PcapWriter | PcapngWriter | None = None
        else:
            self._w = (PcapngWriter if self.kind == "pcapng" else PcapWriter)(out, LINKTYPE_ETHERNET)

    def write(self, frame: Frame) -> None:
        if self._w is None:
            micros = int(round((frame.time or 0.0) * 1e6))
            self._f.write(_TLOG_TIME.pack(max(micros, 0)) + frame.raw)
        else:
            self._w.write(frame.time, synth_udp_ipv4(SYNTH_SRC, SYNTH_DST, frame.raw))

    def close(self) -> None:
        if self._w is None:
            self._f.close()
        else:
            self._w.close()
