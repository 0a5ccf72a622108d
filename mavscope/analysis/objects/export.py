"""The JSON of the object reconstruction: one manifest entry per object (`manifest.json` and
`mavscope objects --json`), the FTP operations, the findings and what the limits gave up."""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping

from mavscope.analysis.objects.model import IMAGE, KINDS, FtpOperation, ObjectRecord
from mavscope.analysis.objects.tracker import ObjectLog
from mavscope.analysis.selection import Selection


def _addr(a: tuple[int, int] | None) -> list[int] | None:
    return None if a is None else [a[0], a[1]]


def manifest_entry(r: ObjectRecord, file: str | None,
                   png: tuple[str | None, str | None] = (None, None)) -> dict[str, object]:
    """One object as the manifest lists it; `file`: its name in the output directory (None: not written);
    `png`: an image's PNG written beside it, or why none was (objects_json)."""
    extra: dict[str, object] = {"png": png[0], "png_not_written": png[1]} if r.kind == IMAGE else {}
    return {**extra,
        "number": r.number, "kind": r.kind, "path": r.path, "name": r.name, "file": file,
        "direction": r.direction, "sender": _addr(r.sender), "receiver": _addr(r.receiver),
        "size": r.size, "sha256": r.sha256, "crc32": f"0x{r.crc32:08x}", "complete": r.complete,
        "end_known": r.end_known, "gaps": [list(g) for g in r.gaps], "gap_unit": r.gap_unit,
        "received": r.received, "announced_size": r.announced_size,
        "start": r.start, "end": r.end, "first_frame": r.first_frame, "last_frame": r.last_frame,
        "frames": list(r.frames), "frame_count": r.frame_count,
        "signatures": {k: dict(v) for k, v in r.signatures.items()},
        "duplicate_bytes": r.duplicate_bytes, "conflict_bytes": r.conflict_bytes, "dropped_bytes": r.dropped_bytes,
        "problems": list(r.problems), "details": dict(r.details),
    }


def operation_json(op: FtpOperation) -> dict[str, object]:
    return {"time": op.time, "frame": op.frame, "client": _addr(op.client), "server": _addr(op.server),
            "opcode": op.opcode, "path": op.path, "new_path": op.new_path, "result": op.result,
            "reply_frame": op.reply_frame, "detail": op.detail}


def objects_json(log: ObjectLog, files: Mapping[int, str] | None = None,
                 selection: Selection | None = None,
                 pngs: Mapping[int, tuple[str | None, str | None]] | None = None) -> dict[str, object]:
    """The objects (with a frame the selection matched), operations, findings and limits.
    `files`: object number -> its file name in the output directory, for those written; `pngs`: image
    number -> (the name of the PNG written beside it, or None and why not)."""
    sel = selection or Selection()
    files = files or {}
    pngs = pngs or {}
    objs = [r for r in log.objects if sel.any_record(r.frames)]
    ops = [op for op in log.operations if sel.any_record((op.frame,))]
    kinds = Counter(r.kind for r in objs)
    return {
        "summary": {"objects": len(objs), "complete": sum(1 for r in objs if r.complete),
                    "by_kind": {k: kinds[k] for k in KINDS if kinds[k]},
                    "bytes": sum(r.size for r in objs), "operations": len(ops)},
        "objects": [manifest_entry(r, files.get(r.number), pngs.get(r.number, (None, None))) for r in objs],
        "operations": [operation_json(op) for op in ops],
        "findings": [f.to_json() for f in log.findings if not sel.active or sel.any_record(f.frames)],
        "limits": {"given_up": dict(log.given_up), "objects_not_kept": log.not_kept},
        "image_orphans": {"frames": log.image_orphans, "first_frames": log.image_orphan_frames[:50]},
    }
