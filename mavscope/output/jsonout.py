"""The JSON Lines / JSON export (contract documented in docs/json-format.md and docs/frame.schema.json)."""

from __future__ import annotations

from collections.abc import Iterable, Iterator

import orjson

from mavscope.mavlink.frame import Frame, SignatureStatus, decode_payload

_dumps = orjson.dumps
_NL = orjson.OPT_APPEND_NEWLINE


def frame_to_json(frame: Frame, fields: dict[str, object] | None = None, decode: bool = True) -> dict[str, object]:
    """The contract object of one frame. `fields` may be passed in when already decoded.

    Float NaN and infinities become null when serialised with orjson (JSON cannot carry them).
    """
    if fields is None and decode:
        fields = decode_payload(frame)
    sig = frame.signature
    md = frame.msgdef
    return {
        "frame": frame.record,
        "index": frame.index,
        "time": frame.time,
        "transport": frame.transport,
        "src": frame.src,
        "dst": frame.dst,
        "version": frame.version,
        "len": frame.length,
        "incompat_flags": frame.incompat_flags,
        "compat_flags": frame.compat_flags,
        "seq": frame.seq,
        "sysid": frame.sysid,
        "compid": frame.compid,
        "msgid": frame.msgid,
        "msgname": md.name if md is not None else None,
        "crc": frame.crc,
        "crc_status": frame.crc_status.value,
        "fields": fields,
        "signature": None
        if sig is None
        else {
            "link_id": sig.link_id,
            "timestamp": sig.timestamp,
            "time": sig.iso_time(),
            "value": sig.value.hex(),
            "status": SignatureStatus.NO_KEY.value,
        },
        "encryption": None,
        "notes": [n.to_json() for n in frame.notes] if frame.notes else [],
    }


def jsonl_bytes(frame: Frame) -> bytes:
    """One JSON Lines line (with its newline) for `frame`."""
    return _dumps(frame_to_json(frame), option=_NL)


def json_array_chunks(frames: Iterable[Frame]) -> Iterator[bytes]:
    """`-T json`: the same objects as one JSON array, streamed."""
    first = True
    yield b"["
    for frame in frames:
        yield (b"\n" if first else b",\n") + _dumps(frame_to_json(frame))
        first = False
    yield b"\n]\n" if not first else b"]\n"
