"""Images sent as DATA_TRANSMISSION_HANDSHAKE and ENCAPSULATED_DATA
(https://mavlink.io/en/services/image_transmission.html, the PX4FLOW's way of sending its camera image).

The sender's handshake announces an image (type, size in bytes, width, height, number of packets,
bytes per packet, JPEG quality); the ENCAPSULATED_DATA frames that follow from the same sender carry
packet `seqnr`, placed at seqnr * payload and cut at the announced size (the first copy of a packet is
kept). The sender's next handshake ends the image. A handshake from another system (the request) names
the receiver; ENCAPSULATED_DATA from a sender with no announced image is counted, not kept. When an image
ends, its bytes say how it reads (`imageformat.read_image`: the format, which numbering of
MAVLINK_DATA_STREAM_TYPE names it, its signature checked), which names its file; `image_findings` says
which images miss packets and which types their bytes contradict.
"""

from __future__ import annotations

from collections.abc import Callable

from mavscope.analysis.objects.context import Context
from mavscope.analysis.objects.imageformat import CONVERTED, HEAD, LABEL, missing_rows, read_image
from mavscope.analysis.objects.imageformat import EXTENSION as FORMAT_EXTENSION
from mavscope.analysis.objects.model import DOWNLOAD, IMAGE, Addr, ObjectRecord, Transfer, int_field, party
from mavscope.analysis.runs import missing_runs
from mavscope.fields.containers.others import ENCAP
from mavscope.mavlink.frame import Frame
from mavscope.notes import Finding, finding

CHUNK = 253  # ENCAPSULATED_DATA.data
# MAVLINK_DATA_STREAM_TYPE -> file extension, where the bytes do not say (common.xml's numbering)
EXTENSIONS = {0: ".jpg", 1: ".bmp", 2: ".raw8u", 3: ".raw32u", 4: ".pgm", 5: ".png"}
MAX_SENDERS = 256
MAX_LISTED = 50  # images named in a finding


class ImageTracker:
    def __init__(self, ctx: Context) -> None:
        self.ctx = ctx
        self.images: dict[Addr, Transfer] = {}  # sender -> the image it announced last
        self.requesters: dict[int, Addr] = {}  # a system that sent a handshake without an image (a request)
        self.orphans = 0  # ENCAPSULATED_DATA frames from a sender with no image announced
        self.orphan_frames: list[int] = []
        self.type_names: dict[int, str] = {}

    def feed(self, f: Frame, name: str, fields: dict[str, object]) -> None:
        me = (f.sysid, f.compid)
        if name == "DATA_TRANSMISSION_HANDSHAKE":
            old = self.images.pop(me, None)
            if old is not None:
                old.closed = True
                self._finish(old)
            size, packets = int_field(fields, "size"), int_field(fields, "packets")
            if size <= 0 or packets <= 0:  # a request (or an empty answer): it names who wants the image
                if len(self.requesters) < MAX_SENDERS:
                    self.requesters[f.sysid] = me
                return
            receiver = next((a for s, a in self.requesters.items() if s != f.sysid), None)
            t = self.ctx.start(IMAGE, DOWNLOAD, me, receiver, self._closer(me))
            t.name = f"image {t.order}"
            t.announced = size
            t.end_at = size
            kind = int_field(fields, "type")
            payload = int_field(fields, "payload") or CHUNK
            t.details.update({"type": kind, "type_name": self.type_names.get(kind, str(kind)),
                              "width": int_field(fields, "width"), "height": int_field(fields, "height"),
                              "packets": packets, "payload": payload, "jpg_quality": int_field(fields, "jpg_quality"),
                              "packets_received": 0, "duplicate_packets": 0, "out_of_range_packets": 0,
                              "_seen": set()})
            t.see(f, self.ctx.tick)
            if len(self.images) >= MAX_SENDERS:
                self._finish(self.images.pop(next(iter(self.images))))
            self.images[me] = t
        elif name == "ENCAPSULATED_DATA":
            image = self.images.get(me)
            if image is None:
                self.orphans += 1
                if len(self.orphan_frames) < self.ctx.limits.max_frames:
                    self.orphan_frames.append(f.record)
                return
            image.see(f, self.ctx.tick)
            d = image.details
            size = image.end_at or 0
            seq = int_field(fields, "seqnr")
            offset = seq * d["payload"]
            if seq >= d["packets"] or offset >= size:
                d["out_of_range_packets"] += 1
                return
            seen: set[int] = d["_seen"]
            if seq in seen:
                d["duplicate_packets"] += 1
            else:
                seen.add(seq)
                d["packets_received"] += 1
            v = ENCAP(f)
            chunk = v.data[: d["payload"]] if v is not None else b""
            image.content.add(offset, chunk[: size - offset])

    def _closer(self, me: Addr) -> Callable[[Transfer], None]:
        def close(t: Transfer) -> None:
            if self.images.get(me) is t:
                del self.images[me]
            self._finish(t)
        return close

    def _finish(self, t: Transfer) -> None:
        d = t.details
        seen: set[int] = d.pop("_seen", set())
        d["missing_packets"] = missing_runs(seen, d["packets"])
        size = t.end_at or 0
        gaps = t.content.gaps(size)
        head_received = not gaps or gaps[0][0] >= min(size, HEAD)
        reading = read_image(d["type"], d["width"], d["height"], size, bytes(t.content.buf[:HEAD]), head_received)
        d.update({"format": reading.format, "numbering": reading.numbering, "signature": reading.signature,
                  "format_problem": reading.problem, "missing_rows": missing_rows(reading.format, d["width"], gaps)})
        if reading.problem:
            t.problem(reading.problem)
        self.ctx.finish(t, size=size, gaps=gaps, end_known=True, complete=not gaps, received=t.content.received,
                        extension=FORMAT_EXTENSION.get(reading.format) or EXTENSIONS.get(d["type"], ".bin"))

    def close_all(self) -> None:
        for me in list(self.images):
            self._finish(self.images.pop(me))


def image_findings(objs: list[ObjectRecord]) -> list[Finding]:
    """`image-incomplete`: images missing ENCAPSULATED_DATA packets (how many, and the rows their PNG holds
    as zeros); `image-format`: images whose bytes contradict their handshake's type, per sender, type and
    format read (the older numbering of MAVLINK_DATA_STREAM_TYPE, PX4FLOW's, is one cause)."""
    images = [r for r in objs if r.kind == IMAGE]
    out = []
    cut = [r for r in images if r.details.get("missing_packets")]
    if cut:
        out.append(finding("image-incomplete", f"{len(cut)} image(s) with ENCAPSULATED_DATA packets missing, "
                                               f"their bytes zeros: {'; '.join(map(_missing, cut[:MAX_LISTED]))}"
                                               f"{' ...' if len(cut) > MAX_LISTED else ''}",
                           [r.first_frame for r in cut[:MAX_LISTED]]))
    kinds: dict[tuple[str, int, str], list[ObjectRecord]] = {}
    for r in images:
        if r.details.get("numbering") != "common.xml":
            kinds.setdefault((party(r.sender), r.details["type"], r.details["format"]), []).append(r)
    for (who, _, _), rs in list(kinds.items())[:MAX_LISTED]:
        why = rs[0].details["format_problem"]
        out.append(finding("image-format", f"{len(rs)} image(s) from {who} ({rs[0].name} first): {why}",
                           [r.first_frame for r in rs[:MAX_LISTED]]))
    return out


def _missing(r: ObjectRecord) -> str:
    d = r.details
    missing = sum(b - a + 1 for a, b in d["missing_packets"])
    rows = ", ".join(f"{a}-{b}" if b > a else str(a) for a, b in d.get("missing_rows", []))
    where = (f"rows {rows} of {d['height']} are zeros in its PNG" if rows else
             "its bytes are written as received" if d.get("format") not in CONVERTED else "its PNG holds them as zeros")
    return f"{r.name} ({d['width']} x {d['height']} {LABEL.get(d.get('format', ''), 'unknown')}): {missing} of " \
           f"{d['packets']} packets missing, {where}"
