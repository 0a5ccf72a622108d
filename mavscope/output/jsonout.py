"""The JSON Lines / JSON export (contract documented in docs/json-format.md and docs/frame.schema.json)."""

from __future__ import annotations

from collections.abc import Iterable, Iterator

import orjson

from mavscope.mavlink.frame import (
    IFLAG_SIGNED,
    CrcStatus,
    Encryption,
    Frame,
    Security,
    Signature,
    SignatureStatus,
    decode_payload,
)

TRUNCATED = CrcStatus.TRUNCATED

_dumps = orjson.dumps
_NL = orjson.OPT_APPEND_NEWLINE


def frame_to_json(frame: Frame, fields: dict[str, object] | None = None, decode: bool = True) -> dict[str, object]:
    """The contract object of one frame. `fields` may be passed in when already decoded.

    Float NaN and infinities become null when serialised with orjson (JSON cannot carry them).
    """
    # One unpacking instead of 20 attribute look-ups: this runs once per frame of a 1M-frame export.
    (record, index, time, transport, src, dst, _, raw, version, length, iflags, cflags, seq, sysid, compid,
     msgid, crc, status, md, sig, notes, _, security) = frame
    if fields is None and decode and md is not None:
        if not iflags & ~IFLAG_SIGNED:
            if status is not TRUNCATED:
                h = 10 if version == 2 else 6
                fields = md.decode(raw[h : h + length])
        else:
            fields = decode_payload(frame)
    return {
        "frame": record,
        "index": index,
        "time": time,
        "transport": transport,
        "src": src,
        "dst": dst,
        "version": version,
        "len": length,
        "incompat_flags": iflags,
        "compat_flags": cflags,
        "seq": seq,
        "sysid": sysid,
        "compid": compid,
        "msgid": msgid,
        "msgname": md.name if md is not None else None,
        "crc": crc,
        "crc_status": status,  # a str Enum: orjson writes its value
        "fields": fields,
        "signature": None if sig is None else signature_json(sig, security, time),
        "encryption": None if security is None or security.encryption is None else encryption_json(security.encryption),
        "notes": [n.to_json() for n in notes] if notes else [],
    }


def signature_json(sig: Signature, security: Security | None = None, time: float | None = None) -> dict[str, object]:
    out: dict[str, object] = {
        "link_id": sig.link_id,
        "timestamp": sig.timestamp,
        "time": sig.iso_time(),
        "value": sig.value.hex(),
        "status": (security.signature_status if security is not None and security.signature_status is not None
                   else SignatureStatus.NO_KEY).value,
    }
    if security is not None and security.key is not None:
        out["key"] = security.key
    if security is not None and time is not None:  # the security layer ran: signature time - capture time
        out["skew"] = round(sig.unix_time - time, 6)
    return out


def encryption_json(enc: Encryption) -> dict[str, object]:
    out: dict[str, object] = {"method": enc.method, "scheme": enc.scheme, "status": enc.status.value}
    if enc.reason:
        out["reason"] = enc.reason
    return out


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
