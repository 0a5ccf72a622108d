"""MAVLink 2 signature verification with per-stream replay state.

signature = SHA-256(secret || header || payload || CRC || link_id || timestamp)[:6], compared in
constant time. A stream is (sysid, compid, link_id); its last accepted timestamp advances only after
a MAC verifies (unlike pymavlink, so a forged frame with a future timestamp cannot block the genuine
ones). A MAC that verifies with a timestamp not newer than the stream's last accepted one is a replay.

New streams: the C library accepts a new stream only when its timestamp is within one minute of the
receiver's clock. Offline, the capture is the clock: mavscope accepts the stream and reports the skew
(signature time - capture time of the frame); beyond `NEW_STREAM_WINDOW` it adds a note, because a
receiver would have rejected the stream (docs/security.md, "Replay rules").
"""

from __future__ import annotations

from hmac import compare_digest
from typing import NamedTuple

from mavscope.mavlink.frame import SignatureReason, SignatureStatus
from mavscope.security.keys import SigningKey
from mavscope.wire import SIGNATURE_LEN

NEW_STREAM_WINDOW = 60.0  # seconds, as the C library's new-stream rule

Stream = tuple[int, int, int]  # (sysid, compid, link_id)


Reason = SignatureReason


class Verdict(NamedTuple):
    status: SignatureStatus
    key: SigningKey | None
    reason: Reason
    detail: str  # numbers for the reason (timestamps, skew); never key material
    skew: float | None = None  # signature time - capture time, seconds, for a new stream


class SignatureVerifier:
    """Checks signed frames against a set of keys, keeping replay state per stream."""

    def __init__(self, keys: list[SigningKey] | None = None) -> None:
        self.keys: list[SigningKey] = list(keys or [])
        self.last: dict[Stream, int] = {}  # last accepted timestamp per stream
        self.stream_key: dict[Stream, SigningKey] = {}  # which key verified the stream last (tried first)

    def add_key(self, key: SigningKey, first: bool = False) -> None:
        if key in self.keys:
            return
        if first:
            self.keys.insert(0, key)
        else:
            self.keys.append(key)

    def match(self, raw: bytes, stream: Stream | None = None) -> SigningKey | None:
        """The key whose MAC matches the signed frame `raw`, or None."""
        value = raw[-6:]
        data = raw[:-6]
        hint = self.stream_key.get(stream) if stream is not None else None
        if hint is not None:
            h = hint._hash.copy()
            h.update(data)
            if compare_digest(h.digest()[:6], value):
                return hint
        for key in self.keys:
            if key is hint:
                continue
            h = key._hash.copy()
            h.update(data)
            if compare_digest(h.digest()[:6], value):
                return key
        return None

    def verify(self, raw: bytes, sysid: int, compid: int, link_id: int, timestamp: int,
               capture_time: float | None, sig_unix_time: float) -> Verdict:
        """The verdict on one signed frame (`raw`: the whole frame, signature included)."""
        if len(raw) < SIGNATURE_LEN + 12:
            return Verdict(SignatureStatus.TRUNCATED, None, Reason.TRUNCATED, "")
        if not self.keys:
            return Verdict(SignatureStatus.NO_KEY, None, Reason.NO_KEY, "")
        stream = (sysid, compid, link_id)
        key = self.match(raw, stream)
        if key is None:
            return Verdict(SignatureStatus.INVALID, None, Reason.NO_KEY_MATCHES, "")
        last = self.last.get(stream)
        if last is not None and timestamp <= last:
            return Verdict(SignatureStatus.REPLAY, key, Reason.NOT_NEWER,
                           f"timestamp {timestamp} <= last accepted {last} on link {link_id}")
        self.last[stream] = timestamp
        self.stream_key[stream] = key
        if last is None:
            skew = None if capture_time is None else sig_unix_time - capture_time
            detail = "" if skew is None else f"signature time {skew:+.6f} s from capture time"
            return Verdict(SignatureStatus.VALID, key, Reason.NEW_STREAM, detail, skew)
        return Verdict(SignatureStatus.VALID, key, Reason.MAC_OK, "")
