"""MAVLink 2 signature verification with per-stream replay state.

signature = SHA-256(secret || header || payload || CRC || link_id || timestamp)[:6], compared in
constant time. A stream is (sysid, compid, link_id); its last accepted timestamp advances only after
a MAC verifies (unlike pymavlink, so a forged frame with a future timestamp cannot block the genuine
ones). A MAC that verifies with a timestamp not newer than the stream's last accepted one is a replay.

New streams: the C library accepts a new stream only when its timestamp is within one minute of the
receiver's clock. Offline, the capture is the clock: mavscope accepts the stream and reports the skew
(signature time - capture time of the frame); beyond `NEW_STREAM_WINDOW` it adds a note, because a
receiver would have rejected the stream (docs/security.md, "Replay rules").

The replay state (per stream the last accepted timestamp and the key that verified it, tried first next
time) lives in a `SigningStore`: `DictSigningStore` here, or with the native engine the C extension's
`SigningState`, which the native walker reads and advances itself, so that a frame judged in C and the
next one judged here see the same state (docs/native.md, "Shared state").
"""

from __future__ import annotations

from hmac import compare_digest
from typing import NamedTuple, Protocol

from mavscope.mavlink.frame import SignatureReason, SignatureStatus
from mavscope.security.keys import SigningKey
from mavscope.wire import SIGNATURE_LEN

NEW_STREAM_WINDOW = 60.0  # seconds, as the C library's new-stream rule
# Keys the capture itself gives (key exchanges, leaked keys) tried on a frame its stream's key does not
# verify. Every such frame costs one MAC per key tried: unbounded, a capture of n exchanges and n forged
# frames cost n * n MACs.
CAPTURE_KEYS = 32

Stream = tuple[int, int, int]  # (sysid, compid, link_id)


Reason = SignatureReason


class Verdict(NamedTuple):
    status: SignatureStatus
    key: SigningKey | None
    reason: Reason
    detail: str  # numbers for the reason (timestamps, skew); never key material
    skew: float | None = None  # signature time - capture time, seconds, for a new stream


class SigningStore(Protocol):
    """Per stream the last accepted timestamp and the slot of the key that verified it last.

    A key gets a slot (`add_key`) before its first `put`; the store may keep what it needs to check that
    key's MACs itself (the native one keeps the hash state after the secret), and never shows it."""

    def add_key(self, secret: bytes, name: str) -> int: ...

    def get(self, stream: Stream) -> tuple[int, int] | None: ...

    def put(self, stream: Stream, last: int, key: int) -> None: ...

    def __len__(self) -> int: ...


class DictSigningStore:
    """The SigningStore of the pure-Python path: a dict. It keeps no key material."""

    __slots__ = ("_streams", "_keys")

    def __init__(self) -> None:
        self._streams: dict[Stream, tuple[int, int]] = {}
        self._keys = 0

    def add_key(self, secret: bytes, name: str) -> int:
        self._keys += 1
        return self._keys - 1

    def get(self, stream: Stream) -> tuple[int, int] | None:
        return self._streams.get(stream)

    def put(self, stream: Stream, last: int, key: int) -> None:
        if not 0 <= key < self._keys:
            raise ValueError("no such key slot")
        self._streams[stream] = (last, key)

    def __len__(self) -> int:
        return len(self._streams)


class SignatureVerifier:
    """Checks signed frames against a set of keys, keeping replay state per stream in `store`.

    Keys the capture gave (`add_key(..., from_capture=True)`) are tried at most `CAPTURE_KEYS` at a time:
    when another comes, the one that least recently verified a frame of a new stream (or came first) is
    no longer tried; the streams it verified keep it (each stream's key is tried first)."""

    def __init__(self, keys: list[SigningKey] | None = None, store: SigningStore | None = None) -> None:
        self.keys: list[SigningKey] = list(keys or [])
        self._tried = set(self.keys)  # the same keys, to look up (a key equals another of its secret)
        self.store: SigningStore = DictSigningStore() if store is None else store
        self._slots: dict[int, int] = {}  # id(key) -> its slot in the store
        self._by_slot: dict[int, SigningKey] = {}  # and back (holding the keys: their ids stay theirs)
        self._from_capture: dict[int, SigningKey] = {}  # id(key) -> key, least recently matched first

    def with_store(self, store: SigningStore) -> SignatureVerifier:
        """A verifier of the same keys, the capture's among them still counted as such, over `store`."""
        new = SignatureVerifier(self.keys, store)
        new._from_capture = dict(self._from_capture)
        return new

    def _slot(self, key: SigningKey) -> int:
        slot = self._slots.get(id(key))
        if slot is None:
            slot = self._slots[id(key)] = self.store.add_key(key.secret, key.name)
            self._by_slot[slot] = key
        return slot

    def add_key(self, key: SigningKey, first: bool = False, from_capture: bool = False) -> SigningKey | None:
        """Try `key` from now on (`first`: before the others). With `from_capture`, the key of the capture
        that this one puts out of the keys tried, if it makes more than CAPTURE_KEYS."""
        if key in self._tried:
            return None
        self._tried.add(key)
        if first:
            self.keys.insert(0, key)
        else:
            self.keys.append(key)
        if not from_capture:
            return None
        self._from_capture[id(key)] = key
        if len(self._from_capture) <= CAPTURE_KEYS:
            return None
        oldest = self._from_capture.pop(next(iter(self._from_capture)))
        self.keys = [k for k in self.keys if k is not oldest]
        self._tried.discard(oldest)
        return oldest

    def match(self, raw: bytes, hint: SigningKey | None = None) -> SigningKey | None:
        """The key whose MAC matches the signed frame `raw` (`hint` tried first), or None."""
        value = raw[-6:]
        data = raw[:-6]
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
                if id(key) in self._from_capture:  # it stays among the keys tried the longest
                    self._from_capture[id(key)] = self._from_capture.pop(id(key))
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
        entry = self.store.get(stream)
        key = self.match(raw, None if entry is None else self._by_slot[entry[1]])
        if key is None:
            return Verdict(SignatureStatus.INVALID, None, Reason.NO_KEY_MATCHES, "")
        last = None if entry is None else entry[0]
        if last is not None and timestamp <= last:
            return Verdict(SignatureStatus.REPLAY, key, Reason.NOT_NEWER,
                           f"timestamp {timestamp} <= last accepted {last} on link {link_id}")
        self.store.put(stream, timestamp, self._slot(key))
        if last is None:
            skew = None if capture_time is None else sig_unix_time - capture_time
            detail = "" if skew is None else f"signature time {skew:+.6f} s from capture time"
            return Verdict(SignatureStatus.VALID, key, Reason.NEW_STREAM, detail, skew)
        return Verdict(SignatureStatus.VALID, key, Reason.MAC_OK, "")
