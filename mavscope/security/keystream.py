"""Fixed keystreams in payload encryption (SecureMAV's XOR and AES-128-CTR restart their keystream for
every frame): repeated ciphertexts, and with one known plaintext the keystream prefix and every other
frame's payload recovered without the key (`audit`, `--known-plaintext`)."""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass, field

from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus, Frame
from mavscope.notes import Finding, finding
from mavscope.security.ciphers import xor_bytes

ENCRYPTED_KEPT = 20_000  # encrypted frames per method the audit looks at (the first ones)


@dataclass
class Recovery:
    record: int
    msgname: str
    recovered: bytes  # payload bytes recovered without the key
    length: int  # encrypted payload length
    fields: dict[str, object] | None = None  # decoded when every byte was recovered


@dataclass
class KeystreamAudit:
    findings: list[Finding] = field(default_factory=list)
    recoveries: list[Recovery] = field(default_factory=list)


def parse_known_plaintext(spec: str, dialect: Dialect) -> tuple[int, bytes]:
    """`MSG=HEX`: a guessed plaintext payload of message MSG (name or id)."""
    from mavscope.errors import UsageError

    name, sep, hexpart = spec.partition("=")
    if not sep:
        raise UsageError("--known-plaintext: expected MSG=HEX (a message name or id and its payload in hex)")
    md = dialect.messages.get(int(name)) if name.isascii() and name.isdigit() else dialect.by_name.get(name.upper())
    if md is None:
        raise UsageError(f"--known-plaintext: unknown message {name!r}")
    try:
        payload = bytes.fromhex(hexpart)
    except ValueError:
        raise UsageError("--known-plaintext: the payload is not valid hex") from None
    return md.id, payload


# Frames whose bytes are not what was sent: their incompat bits say nothing of encryption. (UNCHECKED
# frames, of messages outside the dialects, cannot be checked and are kept: a custom message may be encrypted.)
DAMAGED = frozenset({CrcStatus.BAD, CrcStatus.TRUNCATED})

Plaintexts = dict[tuple[int, int], tuple[int, bytes]]  # (sysid, msgid) -> (record, zero-padded plaintext)


class Collector:
    """What the keystream audit needs, gathered one frame at a time: encrypted frames per method (aes-gcm
    aside: its nonces never repeat a keystream), at most ENCRYPTED_KEPT of each, and the first plaintext
    frame of each message per system (the known plaintexts a capture gives away)."""

    def __init__(self) -> None:
        self.encrypted: dict[int, list[Frame]] = defaultdict(list)
        self.skipped: dict[int, int] = defaultdict(int)  # encrypted frames past ENCRYPTED_KEPT, per method
        self.plain: Plaintexts = {}

    def add(self, f: Frame) -> None:
        if f.crc_status in DAMAGED or f.version != 2:
            return  # the CRC covers the ciphertext: a damaged frame is no evidence of a keystream
        method = f.encryption_method
        if method:
            enc = f.security.encryption if f.security is not None else None
            if enc is None or enc.scheme != "aes-gcm":
                group = self.encrypted[method]
                if len(group) < ENCRYPTED_KEPT:
                    group.append(f)
                else:
                    self.skipped[method] += 1
        elif f.msgdef is not None and not f.incompat_flags & ~1 and f.crc_status is CrcStatus.OK:
            self.plain.setdefault((f.sysid, f.msgid), (f.record, f.payload.ljust(f.msgdef.length, b"\x00")))


def _repeats(method: int, group: list[Frame]) -> Finding | None:
    """Ciphertexts repeated under other sequence numbers: the keystream does not change between frames."""
    seqs: dict[tuple[int, bytes], set[tuple[int, int, int]]] = defaultdict(set)
    firsts: dict[tuple[int, bytes], int] = {}
    for f in group:
        k = (f.msgid, f.payload)
        seqs[k].add((f.sysid, f.compid, f.seq))
        firsts.setdefault(k, f.record)
    repeated = [f for f in group if len(seqs[(f.msgid, f.payload)]) > 1]
    records = [f.record for f in repeated if firsts[(f.msgid, f.payload)] != f.record]
    if not records:
        return None
    names = sorted({f.msgname or str(f.msgid) for f in repeated})
    return finding("keystream-reuse",
                   f"method {method}: {len(records)} of {len(group)} encrypted frames repeat the ciphertext of an "
                   f"earlier frame with another sequence number ({', '.join(names)}): every frame is encrypted with "
                   "the same keystream", records)


def _agreed_prefix(candidates: list[bytes]) -> int:
    """How many leading bytes every keystream candidate agrees on."""
    n = 0
    while all(len(c) > n for c in candidates) and len({c[n] for c in candidates}) == 1:
        n += 1
    return n


def _best_keystream(group: list[Frame], plain: Plaintexts,
                    guesses: dict[int, bytes]) -> tuple[bytes, Frame, str] | None:
    """The longest keystream prefix a known plaintext reveals: (prefix, frame it came from, source).

    Known plaintext: a plaintext frame of the same message from the same system, or a guess. Each
    encrypted frame of that message gives a keystream candidate; a byte is trusted only where every
    candidate agrees (the plaintext may vary between frames: a battery voltage does)."""
    best: tuple[bytes, Frame, str] | None = None
    by_message: dict[tuple[int, int], list[Frame]] = defaultdict(list)
    for f in group:
        by_message[(f.sysid, f.msgid)].append(f)
    for (sysid, msgid), fs in sorted(by_message.items()):
        ref = plain.get((sysid, msgid))
        if ref is not None:
            p, source = ref[1], f"the plaintext {fs[0].msgname} of frame {ref[0]}"
        elif msgid in guesses:
            p, source = guesses[msgid], f"the --known-plaintext {fs[0].msgname}"
        else:
            continue
        candidates = [xor_bytes(f.payload[: len(p)], p[: len(f.payload)]) for f in fs]
        n = _agreed_prefix(candidates)
        if n and (best is None or n > len(best[0])):
            best = (candidates[0][:n], fs[0], f"{source} ({len(fs)} frames agree)")
    return best


def _recover(group: list[Frame], ks: bytes, source_frame: Frame) -> list[Recovery]:
    """Every other frame's payload read with the keystream prefix (decoded where wholly recovered)."""
    out = []
    for f in group:
        if f is source_frame:
            continue
        n = min(len(ks), len(f.payload))
        plain = xor_bytes(f.payload[:n], ks[:n])
        fields = None
        if n == len(f.payload) and f.msgdef is not None and n <= f.msgdef.length:
            fields = f.msgdef.decode(plain)
        out.append(Recovery(f.record, f.msgname or str(f.msgid), plain, len(f.payload), fields))
    return out


def keystream_audit(frames: Iterable[Frame] | Collector, known: Iterable[tuple[int, bytes]] = ()) -> KeystreamAudit:
    """Encrypted frames whose ciphertexts repeat (a keystream that does not change between frames),
    and, given a known plaintext, the keystream prefix and every other frame's recovered bytes."""
    if isinstance(frames, Collector):
        collected = frames
    else:
        collected = Collector()
        for f in frames:
            collected.add(f)
    out = KeystreamAudit()
    plain = collected.plain
    guesses = dict(known)
    for method, group in sorted(collected.encrypted.items()):
        repeated = _repeats(method, group)
        if repeated is not None:
            out.findings.append(repeated)
        best = _best_keystream(group, plain, guesses)
        if best is None:
            continue
        ks, source_frame, source = best
        recoveries = _recover(group, ks, source_frame)
        out.recoveries += recoveries
        full = sum(1 for r in recoveries if r.fields is not None)
        out.findings.append(finding(
            "keystream-reuse",
            f"method {method}: keystream prefix of {len(ks)} bytes recovered from encrypted frame "
            f"{source_frame.record} and {source}; without the key, {len(recoveries)} other encrypted frames are "
            f"readable up to that length, {full} of them completely",
            (source_frame.record, *(r.record for r in recoveries))))
    return out
