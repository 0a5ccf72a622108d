"""The JSON Lines / JSON export (contract documented in docs/json-format.md and docs/frame.schema.json).

The object of a frame is laid out by the field registry (`mavscope.fields.registry.FIELDS`): its
top-level keys are the registered fields' JSON keys in registry order, `fields` holds the decoded
payload (the dialect's field names), `signature` and `encryption` the fields registered in those
blocks, and `notes` the frame's notes. The layout is compiled once into a plan; values the frame holds
as they are exported (`Field.attr`) are read with one `itemgetter`.
"""

from __future__ import annotations

from collections.abc import Callable
from operator import itemgetter

import orjson

from mavscope.fields.registry import ENCRYPTION_BLOCK, FIELDS, MISSING, SIGNATURE_BLOCK, Field
from mavscope.mavlink.floats import shortest_fields
from mavscope.mavlink.frame import CrcStatus, Frame, decode_payload
from mavscope.wire import IFLAG_SIGNED

TRUNCATED = CrcStatus.TRUNCATED

_dumps = orjson.dumps
_NL = orjson.OPT_APPEND_NEWLINE

# A run of top-level keys: (keys, getter, several): with `several`, the getter returns one value per key.
Segment = tuple[tuple[str, ...], Callable[[Frame], object], bool]


def _top_plan() -> tuple[Segment, ...]:
    """The top-level keys in registry order, as segments: consecutive keys the frame holds as they are
    exported (`Field.attr`) share one itemgetter; a computed key has its own getter."""
    slots = {name: i for i, name in enumerate(Frame._fields)}
    segments: list[Segment] = []
    run: list[tuple[str, int]] = []

    def close_run() -> None:
        if run:
            segments.append((tuple(k for k, _ in run), itemgetter(*(i for _, i in run)), len(run) > 1))
            run.clear()

    for f in FIELDS:
        if f.json_key is None or f.json_block is not None:
            continue
        if f.attr is not None and f.json_get is None:
            run.append((f.json_key, slots[f.attr]))
        else:
            close_run()
            segments.append(((f.json_key,), f.json_get or f.get, False))
    close_run()
    return tuple(segments)


_TOP = _top_plan()
_SIGNATURE: tuple[Field, ...] = tuple(f for f in FIELDS if f.json_block == SIGNATURE_BLOCK)
_ENCRYPTION: tuple[Field, ...] = tuple(f for f in FIELDS if f.json_block == ENCRYPTION_BLOCK)


def _block(frame: Frame, fields: tuple[Field, ...]) -> dict[str, object]:
    out: dict[str, object] = {}
    for f in fields:
        v = (f.json_get or f.get)(frame)
        if v is not MISSING:
            out[f.json_key] = v  # type: ignore[index]  # every field of a block has a JSON key
    return out


def frame_to_json(frame: Frame, fields: dict[str, object] | None = None, decode: bool = True) -> dict[str, object]:
    """The contract object of one frame. `fields` may be passed in when already decoded.

    Float NaN and infinities become null when serialised with orjson (JSON cannot carry them).
    """
    out: dict[str, object] = {}
    for keys, get, several in _TOP:
        if several:
            out.update(zip(keys, get(frame)))  # type: ignore[call-overload]  # a tuple, one value per key
        else:
            out[keys[0]] = get(frame)
    md = frame.msgdef
    if fields is None and decode and md is not None:
        if not frame.incompat_flags & ~IFLAG_SIGNED:
            if frame.crc_status is not TRUNCATED:
                h = 10 if frame.version == 2 else 6
                fields = md.decode(frame.raw[h : h + frame.length])
        else:
            fields = decode_payload(frame)
    # a float32 field's number is the shortest decimal that reads back as the same float32 (30.48, not
    # 30.479999542236328; docs/json-format.md), as the native writer's
    out["fields"] = fields if fields is None else shortest_fields(md, fields)
    out["signature"] = None if frame.signature is None else _block(frame, _SIGNATURE)
    sec = frame.security
    out["encryption"] = None if sec is None or sec.encryption is None else _block(frame, _ENCRYPTION)
    out["notes"] = [n.to_json() for n in frame.notes] if frame.notes else []
    return out


def jsonl_bytes(frame: Frame) -> bytes:
    """One JSON Lines line (with its newline) for `frame`."""
    return _dumps(frame_to_json(frame), option=_NL)
