"""`read -w OUT`: write the capture records that hold the frames shown.

Packet captures (pcap, pcapng) are copied record for record with their link types and times: a
`.pcapng` output keeps every link type; a pcap output takes one link type (a capture mixing several
must be written as `.pcapng`). Inputs without a link layer (tlog, raw) have no packets to copy: each
shown frame is wrapped in a synthesised Ethernet/IPv4/UDP packet 127.0.0.1:14550 -> 127.0.0.1:14550,
so Wireshark's MAVLink dissector decodes the file. A `.tlog` output writes tlog entries instead.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from mavscope.capture.base import LINKTYPE_ETHERNET, Record
from mavscope.capture.detect import open_capture
from mavscope.capture.stream import STDIN
from mavscope.capture.synth import endpoint_packet
from mavscope.capture.writer import PcapngWriter, PcapWriter, TlogWriter
from mavscope.endpoint import Endpoint
from mavscope.errors import CaptureError, UsageError
from mavscope.mavlink.frame import Frame
from mavscope.visible import visible

SYNTH_SRC = Endpoint("127.0.0.1", 14550)
SYNTH_DST = Endpoint("127.0.0.1", 14550)


@dataclass(frozen=True, slots=True)
class Written:
    """What `-w` wrote: the record count, and a one-line warning if record times had to be clamped."""

    count: int
    warning: str | None = None


def _output_kind(out: str | os.PathLike[str]) -> str:
    suffix = Path(out).suffix.lower()
    return {".pcapng": "pcapng", ".tlog": "tlog"}.get(suffix, "pcap")


def open_output(out: str | os.PathLike[str]) -> BinaryIO:
    """`out` opened for writing, so that an unwritable path is refused before a long read, not after it."""
    try:
        return open(out, "wb")  # noqa: SIM115 - the caller closes it
    except OSError as e:
        raise CaptureError(f"cannot write: {e.strerror or e}", path=os.fspath(out)) from None


def write_records(source: str | os.PathLike[str], out: str | os.PathLike[str], records: set[int],
                  file: BinaryIO | None = None, comments: Mapping[int, Sequence[str]] | None = None) -> Written:
    """Copy the records numbered in `records` from the packet capture `source` to `out` (or to `file`,
    already opened for `out` by open_output, left open); a pcapng `out` carries each record's `comments`
    (its frames' verdicts: frame_comment) as packet comments, which a pcap cannot hold."""
    comments = comments or {}
    kind = _output_kind(out)
    if kind == "tlog":
        raise UsageError("-w: a packet capture can be written as .pcap or .pcapng, not .tlog")
    if os.fspath(source) == STDIN:
        raise UsageError("-w: the records of standard input cannot be read again to be written: save the capture "
                         "to a file first (tshark -w FILE, tcpdump -w FILE) and read that")
    target: str | os.PathLike[str] | BinaryIO = file if file is not None else out
    with open_capture(source) as reader:
        chosen: Iterable[Record] = (r for r in reader if r.number in records and r.linktype >= 0)
        if kind == "pcapng":
            with PcapngWriter(target) as w:
                n = 0
                for rec in chosen:
                    w.write(rec.time, rec.data, rec.orig_len, linktype=rec.linktype,
                            comments=comments.get(rec.number, ()))
                    n += 1
            return Written(n, w.clamp_message())
        writer: PcapWriter | None = None
        n = 0
        try:
            for rec in chosen:
                if writer is None:
                    writer = PcapWriter(target, rec.linktype)
                elif rec.linktype != writer.linktype:
                    raise UsageError("-w: the frames shown come from several link types; write them as " + (
                        "a .pcapng file (- writes pcap)" if os.fspath(out) == "-" else
                        Path(out).with_suffix(".pcapng").name))
                writer.write(rec.time, rec.data, rec.orig_len)
                n += 1
            if writer is None:
                writer = PcapWriter(target, LINKTYPE_ETHERNET)
        finally:
            if writer is not None:
                writer.close()
        return Written(n, writer.clamp_message())


def frame_comment(frame: Frame) -> str:
    """The packet comment `-w OUT.pcapng` gives a shown frame: its number, message and sender, its CRC and
    signature verdicts, decryption, and each note with its severity, as Wireshark's expert info reads
    (`mavscope: frame 4.2 ATTITUDE from 1/1: CRC bad; note warn bad-crc: CRC 0x1234 does not match the
    frame`). Text from the capture or a dialect is escaped (visible)."""
    words = [f"CRC {frame.crc_status.value}"]
    status = frame.signature_status
    sec = frame.security
    if status is not None:
        reason = f" ({sec.reason_text})" if sec is not None and sec.reason is not None else ""
        words.append(f"signature {status.value}{reason}")
    if sec is not None and sec.encryption is not None:
        words.append(f"payload {sec.encryption.status.value}")
    words += [f"note {n.severity.value} {n.code}: {n.message}" for n in frame.notes]
    name = frame.msgname or f"message {frame.msgid}"
    return visible(f"mavscope: frame {frame.number} {name} from {frame.sysid}/{frame.compid}: {'; '.join(words)}")


class FrameWriter:
    """Writes shown frames of a tlog or raw input to a pcap, pcapng or tlog file as they come (to `file`,
    opened for `out`, when given: standard output for `read -w -`, left open)."""

    def __init__(self, out: str | os.PathLike[str], file: BinaryIO | None = None) -> None:
        self.kind = _output_kind(out)
        self.count = 0
        self._w: TlogWriter | PcapWriter | PcapngWriter
        target: str | os.PathLike[str] | BinaryIO = file if file is not None else out
        if self.kind == "tlog":
            self._w = TlogWriter(target)
        else:
            self._w = (PcapngWriter if self.kind == "pcapng" else PcapWriter)(target, LINKTYPE_ETHERNET)

    def write(self, frame: Frame) -> None:
        if isinstance(self._w, TlogWriter):
            self._w.write(frame.time, frame.raw)
        elif isinstance(self._w, PcapngWriter):
            self._w.write(frame.time, endpoint_packet(SYNTH_SRC, SYNTH_DST, frame.raw), comments=[frame_comment(frame)])
        else:
            self._w.write(frame.time, endpoint_packet(SYNTH_SRC, SYNTH_DST, frame.raw))
        self.count += 1

    def close(self) -> Written:
        """Close the file (idempotent); what was written."""
        self._w.close()
        return Written(self.count, self._w.clamp_message())
