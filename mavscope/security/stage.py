"""The security stage of the pipeline: signature verdicts, decryption, and the key-free notes.

`SecurityStage(material).run(items)` passes every item on; a frame it has something to say about
comes out as `frame._replace(security=Security(...), notes=...)`. It always runs (method 7 needs no
key; `key-leak` and `unsigned-in-signed-stream` need none), and frames it has nothing to say about
pass through untouched on a fast path.

Rules (docs/security.md):
- Signed frames: `valid` / `invalid` / `replay` / `no-key` from `SignatureVerifier`, checked over
  the frame as sent (ciphertext included), before any decryption.
- `unsigned-in-signed-stream` (a v2 frame) or `v1-in-signed-stream` (a MAVLink v1 frame, which cannot
  carry a signature): an unsigned frame (not RADIO_STATUS) from a (sysid, compid) that has
  sent a validly signed frame; without any signing key material, one that has sent a signed frame
  with a good CRC.
- `key-leak`: SETUP_SIGNING (its key travels in clear); with `use_leaked_keys` that key verifies the
  frames after it.
- MAVSCOPE_KEY_EXCHANGE with `--ecdh-private`: each peer public key opens an epoch whose keys
  verify and decrypt the frames after it.
- Live capture may hand the stage new key material while it runs (`replace_material`, from another
  thread); the stage starts over with it between two frames, after the frames seen so far are judged
  again. NOTE_CODES are the notes this stage adds (what a second judgement replaces).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable, Iterator
from typing import cast

from mavscope.mavlink.frame import (
    CrcStatus,
    Encryption,
    EncryptionStatus,
    Frame,
    Security,
    SignatureReason,
    SignatureStatus,
)
from mavscope.notes import Note, note
from mavscope.pipeline.dissect import Anomaly
from mavscope.security.ciphers import CipherError, FixedKeystream, gcm_nonce, gcm_open, gcm_session_key
from mavscope.security.kex import KEY_EXCHANGE_MSGID, KeyExchangeTracker
from mavscope.security.keys import (
    AES_GCM_DEFAULT_METHOD,
    SECUREMAV_TEST_METHOD,
    SECUREMAV_TEST_XOR,
    CipherKey,
    KeyMaterial,
    SigningKey,
)
from mavscope.security.signing import CAPTURE_KEYS, NEW_STREAM_WINDOW, DictSigningStore, SignatureVerifier, SigningStore
from mavscope.wire import IFLAG_SIGNED

SETUP_SIGNING = 256
RADIO_STATUS = 109
_TRUNCATED = CrcStatus.TRUNCATED
_OK = CrcStatus.OK
_SPECIAL = frozenset({SETUP_SIGNING, KEY_EXCHANGE_MSGID})
NOTE_CODES = frozenset({"signature-skew", "unsigned-in-signed-stream", "v1-in-signed-stream", "key-leak",
                        "key-exchange", "nonce-reuse"})


class SignedSenders(set[tuple[int, int]]):
    """The senders seen signing, (sysid, compid): a set that also keeps those added, in order (`log`), and
    counts its clears (`epoch`), so that the native walker, which must know them before each batch, reads
    only the new ones (reading the whole set before every batch was quadratic: docs/native.md). Only `add`
    and `clear` keep the log; the stage changes the set through them alone. `add` ignores a sender already
    there, so the log holds each sender once per epoch."""

    __slots__ = ("log", "epoch")

    def __init__(self) -> None:
        super().__init__()
        self.log: list[tuple[int, int]] = []
        self.epoch = 0

    def add(self, sender: tuple[int, int]) -> None:
        if sender not in self:
            set.add(self, sender)
            self.log.append(sender)

    def clear(self) -> None:
        set.clear(self)
        self.log = []
        self.epoch += 1


def unsigned_note(version: int, message: str, sender: str, offset: int | None) -> tuple[SignatureReason, Note]:
    """The verdict and note of an unsigned frame (MAVLink 1 or 2) of message `message` from `sender`
    ("sysid/compid"), a sender that signs (but RADIO_STATUS, which a radio adds unsigned). The native walker
    writes the same note from a template made of this one (mavscope.native.walk.note_templates)."""
    what = f"{message} from {sender}, which sends signed frames"
    if version == 1:
        return SignatureReason.V1_IN_SIGNED_STREAM, note("v1-in-signed-stream", f"MAVLink v1 {what}", offset)
    return SignatureReason.UNSIGNED_IN_SIGNED_STREAM, note("unsigned-in-signed-stream", f"unsigned {what}", offset)


def with_unsigned_note(frame: Frame) -> Frame:
    """`frame` (unsigned, of a sender that signs, plaintext, no key message) as `SecurityStage.process` gives
    it (the native walker's column mode gives such a frame as a code: mavscope.native.windows.noted)."""
    reason, n = unsigned_note(frame.version, str(frame.msgname or frame.msgid), f"{frame.sysid}/{frame.compid}",
                              frame.offset)
    return frame._replace(security=Security(None, None, None, reason, "", None), notes=(*frame.notes, n))


class SecurityStage:
    """One instance per capture: it keeps the replay state, the senders seen signing, the epochs."""

    def __init__(self, material: KeyMaterial | None = None,
                 signing_store: Callable[[], SigningStore] = DictSigningStore) -> None:
        self.signed_senders = SignedSenders()  # one set for good: run() holds it
        self._new_store = signing_store  # where each verifier keeps its replay state
        self._incoming: list[tuple[KeyMaterial, Callable[[SecurityStage], object] | None]] = []
        self._incoming_lock = threading.Lock()
        self._taking = False
        self._setup(material or KeyMaterial())

    def _setup(self, material: KeyMaterial) -> None:
        """Start over with `material`: keys, ciphers, and empty replay, sender and epoch state."""
        self.material = m = material
        self.verifier = SignatureVerifier(m.signing, self._new_store())
        self.check_signatures = m.has_signing_material
        self.kex = KeyExchangeTracker(m.ecdh_private)
        self.ciphers: dict[int, CipherKey] = dict(m.ciphers)
        if m.ecdh_private and not any(c.from_ecdh for c in self.ciphers.values()):
            self.ciphers.setdefault(AES_GCM_DEFAULT_METHOD,
                                    CipherKey(AES_GCM_DEFAULT_METHOD, "aes-gcm", b"", from_ecdh=True))
        self.ciphers.setdefault(SECUREMAV_TEST_METHOD, CipherKey(SECUREMAV_TEST_METHOD, "xor", SECUREMAV_TEST_XOR))
        self.keystreams: dict[int, FixedKeystream] = {}
        for method, c in self.ciphers.items():
            if c.scheme == "xor":
                self.keystreams[method] = FixedKeystream.xor(c.key)
            elif c.scheme == "aes-128-ctr":
                self.keystreams[method] = FixedKeystream.aes_ctr(c.key, c.iv)
        self.session_keys: dict[tuple[bytes, int], bytes] = {}
        self.nonces: dict[tuple[bytes, int, int], tuple[int, bytes]] = {}
        self.signed_senders.clear()

    def use_signing_store(self, new: Callable[[], SigningStore]) -> None:
        """Keep the replay state in stores made by `new` from now on (the native engine's SigningState,
        which its walker shares), starting with the current verifier's: only before it holds any."""
        if len(self.verifier.store):
            raise RuntimeError("the signing state already holds streams")
        self._new_store = new
        self.verifier = self.verifier.with_store(new())

    def add_signing_key(self, key: SigningKey, first: bool = False, from_capture: bool = False) -> str:
        """Verify with `key` from now on; for a key of the capture, what became of the keys tried (text
        for the frame's note: "" or the key no longer tried, see `SignatureVerifier`)."""
        retired = self.verifier.add_key(key, first, from_capture)
        self.check_signatures = True
        if retired is None:
            return ""
        return (f"; key {retired.name} is no longer tried on new streams (at most {CAPTURE_KEYS} keys from the "
                "capture are; streams it verified keep it)")

    def replace_material(self, material: KeyMaterial,
                         then: Callable[[SecurityStage], object] | None = None) -> None:
        """New key material, from any thread (live capture): the stage's own thread takes it between
        two frames (`run` before its next item, or `take_material` while no frame comes), starts over
        with it, and calls `then(stage)` there, before the next frame: the place to judge again the
        frames seen so far (see `FrameIndex.rejudge`), which also rebuilds the replay state."""
        with self._incoming_lock:
            self._incoming.append((material, then))

    def take_material(self) -> None:
        """Apply what `replace_material` handed over (call from the thread that runs the stage)."""
        if not self._incoming or self._taking:
            return
        with self._incoming_lock:
            incoming, self._incoming = self._incoming, []
        self._taking = True  # `then` runs frames through this stage: not again from inside it
        try:
            for material, then in incoming:
                self._setup(material)
                if then is not None:
                    then(self)
        finally:
            self._taking = False

    def run(self, items: Iterable[Frame | Anomaly]) -> Iterator[Frame | Anomaly]:
        process = self.process
        senders = self.signed_senders
        special = _SPECIAL
        for item in items:
            if self._incoming:
                self.take_material()
            # fast path: a plaintext unsigned frame from a sender that never signed, not a key message
            if type(item) is Anomaly or (not item.incompat_flags and item.msgid not in special
                                         and (item.sysid, item.compid) not in senders):
                yield item
                continue
            yield process(item)

    def process(self, frame: Frame) -> Frame:
        iflags = frame.incompat_flags
        sender = (frame.sysid, frame.compid)
        notes: list[Note] = []
        status: SignatureStatus | None = None
        key_name: str | None = None
        reason: SignatureReason | None = None
        detail = ""
        skew: float | None = None
        sig = frame.signature
        if frame.version == 2 and iflags & IFLAG_SIGNED:
            if sig is None or frame.crc_status is _TRUNCATED:
                status = SignatureStatus.TRUNCATED
            elif self.check_signatures:
                v = self.verifier.verify(frame.raw, frame.sysid, frame.compid, sig.link_id, sig.timestamp,
                                         frame.time, sig.unix_time)
                status = v.status
                key_name = v.key.name if v.key is not None else None
                reason, detail, skew = v.reason, v.detail, v.skew
                # the membership test first: a signed frame's sender is nearly always known, and the C test
                # is cheaper than calling SignedSenders.add (which tests again, for its log)
                if status is SignatureStatus.VALID and sender not in self.signed_senders:
                    self.signed_senders.add(sender)
                if v.skew is not None and abs(v.skew) > NEW_STREAM_WINDOW:
                    notes.append(note("signature-skew", _skew_text(sig.link_id, v.skew), frame.offset))
            elif frame.crc_status is _OK and sender not in self.signed_senders:
                self.signed_senders.add(sender)
        elif sender in self.signed_senders and frame.msgid != RADIO_STATUS:
            reason, n = unsigned_note(frame.version, str(frame.msgname or frame.msgid), f"{sender[0]}/{sender[1]}",
                                      frame.offset)
            notes.append(n)
        enc: Encryption | None = None
        if frame.version == 2 and iflags & 0xE0:
            enc = self.decrypt(frame, notes)
        if frame.msgid in _SPECIAL and frame.crc_status is _OK and frame.msgdef is not None:
            plain = frame.payload if enc is None else enc.plaintext
            if plain is not None:
                self.key_message(frame, frame.msgdef.decode(plain), notes)
        if status is None and enc is None and not notes and reason is None:
            return frame
        security = Security(status, key_name, enc, reason, detail, skew)
        if notes:
            return frame._replace(security=security, notes=frame.notes + tuple(notes))
        return frame._replace(security=security)

    # --- key messages -----------------------------------------------------------------------

    def key_message(self, frame: Frame, fields: dict[str, object], notes: list[Note]) -> None:
        if frame.msgid == SETUP_SIGNING:
            key_bytes = cast("Iterable[int]", fields.get("secret_key", ()))  # uint8_t[32]: a list of ints
            secret = bytes(int(b) & 0xFF for b in key_bytes)
            target = f"{fields.get('target_system')}/{fields.get('target_component')}"
            if not any(secret):
                notes.append(note("key-leak", f"SETUP_SIGNING to {target} with an all-zero key (signing disabled)",
                                  frame.offset))
                return
            used = ""
            if self.material.use_leaked_keys and len(secret) == 32:
                key = SigningKey(f"leaked-{frame.record}", secret)
                used = f"; it verifies later frames as key {key.name}" + self.add_signing_key(key, from_capture=True)
            notes.append(note("key-leak", f"SETUP_SIGNING to {target} carries a signing key in clear{used}",
                              frame.offset))
        else:
            epoch, text = self.kex.observe(fields, frame.sysid, frame.compid, frame.record)
            if epoch is not None:
                text += self.add_signing_key(epoch.signing, first=True, from_capture=True)
            notes.append(note("key-exchange", text, frame.offset))

    # --- decryption -------------------------------------------------------------------------

    def decrypt(self, frame: Frame, notes: list[Note]) -> Encryption:
        method = frame.incompat_flags >> 5
        cipher = self.ciphers.get(method)
        if cipher is None:
            return Encryption(method, None, EncryptionStatus.NO_KEY, None, f"no cipher for method {method} (--cipher)")
        scheme = cipher.scheme
        if frame.crc_status is _TRUNCATED:
            return Encryption(method, scheme, EncryptionStatus.FAILED, None, "frame truncated")
        payload = frame.payload
        if scheme == "aes-gcm":
            try:
                nonce = gcm_nonce(payload)
            except CipherError as exc:
                return Encryption(method, scheme, EncryptionStatus.FAILED, None, str(exc))
            if cipher.from_ecdh:
                epoch = self.kex.epochs.get(nonce.session_id)
                if epoch is None:
                    return Encryption(method, scheme, EncryptionStatus.NO_KEY, None,
                                      f"no key exchange for session id {nonce.session_id}")
                master = epoch.gcm_master
            else:
                master = cipher.key
            sk = self.session_keys.get((master, nonce.session_id))
            if sk is None:
                sk = self.session_keys[(master, nonce.session_id)] = gcm_session_key(master, nonce.session_id)
            try:
                plain = gcm_open(sk, frame.raw[:10], payload)
            except CipherError as exc:
                return Encryption(method, scheme, EncryptionStatus.FAILED, None, str(exc))
            seen = self.nonces.setdefault((master, nonce.session_id, nonce.counter), (frame.record, payload))
            if seen[1] != payload:
                notes.append(note("nonce-reuse", f"aes-gcm nonce (session {nonce.session_id}, counter {nonce.counter}) "
                                  f"already used in frame {seen[0]} for another plaintext", frame.offset))
        else:
            plain = self.keystreams[method].apply(payload)
        md = frame.msgdef
        if md is not None and len(plain) > md.length:
            return Encryption(method, scheme, EncryptionStatus.FAILED, None,
                              f"decrypted payload of {len(plain)} bytes is longer than {md.name} ({md.length})")
        return Encryption(method, scheme, EncryptionStatus.DECRYPTED, plain)


def _skew_text(link_id: int, skew: float) -> str:
    """What a receiver whose signing clock is the capture's does with a new stream `skew` s off: the C
    library refuses one more than a minute old, and takes one from the future, moving its clock forward."""
    if skew < 0:
        return (f"new signing stream (link {link_id}) with a timestamp {-skew:.3f} s before capture time: a "
                "receiver refuses a new stream more than a minute old")
    return (f"new signing stream (link {link_id}) with a timestamp {skew:.3f} s after capture time: a receiver "
            "takes it and moves its signing clock forward, then refuses new streams with the true time")
