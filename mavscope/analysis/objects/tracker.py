"""The object reconstruction in one pass: `ObjectTracker.feed(frame)` for every frame in capture order,
`take()` for the objects finished so far (with their bytes, which the tracker then lets go of), and
`finish()` for the `ObjectLog`: every object, the FTP operations, the findings and what a limit made it
give up. `analyse(frames)` is the one-call form.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from mavscope.analysis.objects.context import Context
from mavscope.analysis.objects.ftp import FtpTracker
from mavscope.analysis.objects.images import ImageTracker, image_findings
from mavscope.analysis.objects.logs import LogTracker
from mavscope.analysis.objects.model import FTP_WRITE, FtpOperation, Limits, ObjectRecord, party
from mavscope.analysis.objects.names import unsafe_reasons
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus, Frame, decode_payload
from mavscope.notes import Finding, finding, sort_findings
from mavscope.visible import quoted

FTP_MESSAGE = "FILE_TRANSFER_PROTOCOL"
LOG_MESSAGES = frozenset({"LOG_ENTRY", "LOG_REQUEST_DATA", "LOG_DATA", "LOG_REQUEST_END"})
IMAGE_MESSAGES = frozenset({"DATA_TRANSMISSION_HANDSHAKE", "ENCAPSULATED_DATA"})
TRACKED_MESSAGES = LOG_MESSAGES | IMAGE_MESSAGES | {FTP_MESSAGE}
# Where an uploaded file runs as code: ArduPilot's Lua scripts (APM/scripts/*.lua, run at boot when
# SCR_ENABLE is set), PX4's startup additions on the SD card (etc/extras.txt, etc/config.txt, etc/rc.*).
SCRIPT_PATHS = re.compile(r"(^|/)scripts/[^/]+\.lua$|(^|/)etc/(extras\.txt|config\.txt|rc\.[^/]+)$", re.IGNORECASE)
MAX_LISTED = 50


@dataclass
class ObjectLog:
    """Everything the reconstruction found in a capture."""

    objects: list[ObjectRecord]  # by number (the order the transfers started)
    operations: list[FtpOperation]
    findings: list[Finding]
    given_up: dict[str, int]  # what a limit made it give up -> how often
    image_orphans: int  # ENCAPSULATED_DATA frames from a sender that announced no image
    image_orphan_frames: list[int]
    not_kept: int  # objects finished beyond Limits.max_objects


class ObjectTracker:
    def __init__(self, limits: Limits | None = None, *, ftp_paths: Callable[[str], bool] | None = None,
                 ftp_only: bool = False) -> None:
        """`ftp_paths`: follow only FTP reads and writes of these paths; `ftp_only`: no logs, no images."""
        self.ctx = Context(limits or Limits())
        self.ftp = FtpTracker(self.ctx, ftp_paths)
        self.logs = LogTracker(self.ctx)
        self.images = ImageTracker(self.ctx)
        self.ftp_only = ftp_only

    def feed(self, f: Frame, fields: dict[str, object] | None = None) -> None:
        """`fields`: the frame's payload where the caller has decoded it already (so it is not decoded twice)."""
        self.ctx.tick += 1
        md = f.msgdef
        if md is None or f.crc_status is not CrcStatus.OK:
            return
        name = md.name
        if name == FTP_MESSAGE:
            self.ftp.feed(f)
        elif not self.ftp_only and (name in LOG_MESSAGES or name in IMAGE_MESSAGES):
            if fields is None:
                fields = decode_payload(f)
            if fields is None:
                return
            if name in LOG_MESSAGES:
                self.logs.feed(f, name, fields)
            else:
                self.images.feed(f, name, fields)

    def use_dialect(self, dialect: Dialect) -> None:
        """Name image types from the dialect's MAVLINK_DATA_STREAM_TYPE."""
        enum = dialect.enums.get("MAVLINK_DATA_STREAM_TYPE")
        if enum is not None:
            self.images.type_names = {v: e.name for v, e in enum.entries.items()}

    @property
    def finished_waiting(self) -> bool:
        """Whether objects finished since the last take() wait to be taken."""
        return bool(self.ctx.fresh)

    def take(self) -> list[ObjectRecord]:
        """The objects finished since the last call, with their bytes (the tracker keeps them without)."""
        return self.ctx.take()

    def finish(self) -> ObjectLog:
        self.ftp.close_all()
        self.logs.close_all()
        self.images.close_all()
        self.ctx.close_all()
        ctx = self.ctx
        objects = sorted(ctx.records, key=lambda r: r.number)
        ops = [op.freeze() for op in ctx.ops if not op.became_object]
        log = ObjectLog(objects, ops, [], dict(ctx.given_up), self.images.orphans,
                        list(self.images.orphan_frames), ctx.not_kept)
        log.findings = object_findings(log)
        return log


def object_findings(log: ObjectLog) -> list[Finding]:
    out: list[Finding] = []
    objs = log.objects
    uploads = [r for r in objs if r.kind == FTP_WRITE]
    if uploads:
        listed = "; ".join(f"{r.path or r.name} ({r.size:,} bytes, {party(r.sender)} to {party(r.receiver)}, "
                           f"{'complete' if r.complete else 'incomplete'})" for r in uploads[:MAX_LISTED])
        out.append(finding("ftp-upload", f"{len(uploads)} file(s) written to a vehicle over MAVLink FTP: {listed}",
                           [r.first_frame for r in uploads[:MAX_LISTED]]))
    for r in uploads:
        if r.path is not None and SCRIPT_PATHS.search(r.path):
            signed = "signed" if r.signed_frames else "unsigned"
            out.append(finding("script-upload", f"{r.path} ({r.size:,} bytes) written by {party(r.sender)} to "
                                                f"{party(r.receiver)} over {signed} frames: a file the vehicle "
                                                f"runs as code", [r.first_frame, r.last_frame]))
    for r in objs:
        if r.conflict_bytes:
            out.append(finding("object-conflict", f"{r.name}: {r.conflict_bytes:,} byte(s) received again with "
                                                  f"other values (the first copy is kept)",
                               [r.first_frame, r.last_frame]))
    unsafe: list[tuple[str, list[str], int]] = []
    for r in objs:
        if r.path is not None and (why := unsafe_reasons(r.path)):
            unsafe.append((r.path, why, r.first_frame))
    for op in log.operations:
        for p in (op.path, op.new_path):
            if p is not None and (why := unsafe_reasons(p)):
                unsafe.append((p, why, op.frame))
    if unsafe:
        text = "; ".join(f"{quoted(p)}: {', '.join(why)}" for p, why, _ in unsafe[:MAX_LISTED])  # (shown escaped)
        out.append(finding("object-unsafe-path", f"{len(unsafe)} vehicle path(s) that cannot be used as file "
                                                 f"names as they are ({text}); their files are named safely",
                           [n for _, _, n in unsafe[:MAX_LISTED]]))
    out += image_findings(objs)
    if log.given_up:
        text = "; ".join(f"{k} ({v}x)" if v > 1 else k for k, v in list(log.given_up.items())[:MAX_LISTED])
        out.append(finding("object-limit", f"limits of the reconstruction cut some data: {text}"))
    return sort_findings(out)


def analyse(frames: Iterable[Frame], dialect: Dialect | None = None, limits: Limits | None = None) -> ObjectLog:
    """Every object of `frames` (in capture order), with their bytes."""
    tracker = ObjectTracker(limits)
    if dialect is not None:
        tracker.use_dialect(dialect)
    for f in frames:
        tracker.feed(f)
    return tracker.finish()
