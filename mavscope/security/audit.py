"""Audits over a capture's security verdicts: dictionary attacks on the signing passphrase, fixed
keystreams in payload encryption, and summaries of the stage's verdicts (`mavscope audit`).

Everything here returns `Finding`s (and, for keystream recovery, the recovered bytes); presentation
is the command's job. The one finding that prints a secret is `weak-passphrase`: reporting the
passphrase a dictionary found is the point of that audit (docs/security.md).
"""

from __future__ import annotations

import hashlib
import time
from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass, field
from hmac import compare_digest

from mavscope.analysis.findings import Finding, sort_findings
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus, EncryptionStatus, Frame, SignatureStatus
from mavscope.notes import Severity
from mavscope.security.ciphers import xor_bytes
from mavscope.security.keys import QGC_ITERATIONS, QGC_SALT

SHOWN = 8  # frames listed by number in a message


def _frames_text(records: list[int]) -> str:
    head = ", ".join(map(str, records[:SHOWN]))
    return head + (f" and {len(records) - SHOWN} more" if len(records) > SHOWN else "")


# --- dictionary attack on the signing passphrase --------------------------------------------------


@dataclass(frozen=True)
class CrackResult:
    passphrase: str | None
    derivation: str  # "sha256" or "qgc"
    guesses: int
    seconds: float

    @property
    def rate(self) -> float:
        return self.guesses / self.seconds if self.seconds > 0 else float("inf")


def crack_sha256(raw: bytes, words: Iterable[bytes]) -> CrackResult:
    """Try SHA-256(word) as the signing key of the signed frame `raw`."""
    data, value = raw[:-6], raw[-6:]
    sha = hashlib.sha256
    n = 0
    t0 = time.perf_counter()
    for word in words:
        n += 1
        if compare_digest(sha(sha(word).digest() + data).digest()[:6], value):
            return CrackResult(word.decode("utf-8", "replace"), "sha256", n, time.perf_counter() - t0)
    return CrackResult(None, "sha256", n, time.perf_counter() - t0)


def crack_qgc(raw: bytes, words: Iterable[bytes], iterations: int = QGC_ITERATIONS) -> CrackResult:
    """Try QGroundControl's PBKDF2-HMAC-SHA256 derivation of each word (slow by design)."""
    data, value = raw[:-6], raw[-6:]
    n = 0
    t0 = time.perf_counter()
    for word in words:
        n += 1
        key = hashlib.pbkdf2_hmac("sha256", word, QGC_SALT, iterations, 32)
        if compare_digest(hashlib.sha256(key + data).digest()[:6], value):
            return CrackResult(word.decode("utf-8", "replace"), "qgc", n, time.perf_counter() - t0)
    return CrackResult(None, "qgc", n, time.perf_counter() - t0)


def read_wordlist(path: str) -> list[bytes]:
    with open(path, "rb") as fh:
        return [w for w in (line.rstrip(b"\r\n") for line in fh) if w]


def passphrase_findings(frames: list[Frame], words: list[bytes], qgc: bool) -> list[Finding]:
    target = next((f for f in frames if f.signature is not None and f.crc_status is CrcStatus.OK), None)
    if target is None:
        return [Finding("passphrase-not-found", Severity.NOTE, "no signed frame with a good CRC to test a wordlist on")]
    results = [crack_sha256(target.raw, words)]
    if results[0].passphrase is None and qgc:
        results.append(crack_qgc(target.raw, words))
    speeds = "; ".join(f"{r.guesses} {'SHA-256' if r.derivation == 'sha256' else 'QGC PBKDF2'} guesses in "
                       f"{r.seconds:.3f} s ({r.rate:,.0f}/s)" for r in results)
    found = results[-1]
    if found.passphrase is not None:
        how = ("SHA-256(passphrase), as MAVProxy and older QGroundControl" if found.derivation == "sha256"
               else "PBKDF2-HMAC-SHA256, 600000 iterations, as current QGroundControl")
        return [Finding("weak-passphrase", Severity.ERROR,
                        f"signing passphrase {found.passphrase!r} is in the wordlist (key = {how}); it verifies "
                        f"frame {target.record}; {speeds}", (target.record,))]
    tried = "SHA-256" + (" and QGC PBKDF2" if qgc else "")
    return [Finding("passphrase-not-found", Severity.NOTE,
                    f"no word of the wordlist ({len(words)} words, {tried}) derives the signing key of frame "
                    f"{target.record}; {speeds}", (target.record,))]


# --- fixed keystreams ----------------------------------------------------------------------------


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
    md = dialect.messages.get(int(name)) if name.isdigit() else dialect.by_name.get(name.upper())
    if md is None:
        raise UsageError(f"--known-plaintext: unknown message {name!r}")
    try:
        payload = bytes.fromhex(hexpart)
    except ValueError:
        raise UsageError("--known-plaintext: the payload is not valid hex") from None
    return md.id, payload


def keystream_audit(frames: list[Frame], known: list[tuple[int, bytes]] = ()) -> KeystreamAudit:  # type: ignore[assignment]
    """Encrypted frames whose ciphertexts repeat (a keystream that does not change between frames),
    and, given a known plaintext, the keystream prefix and every other frame's recovered bytes."""
    out = KeystreamAudit()
    encrypted: dict[int, list[Frame]] = defaultdict(list)
    plain_ref: dict[tuple[int, int], tuple[int, bytes]] = {}  # (sysid, msgid) -> (record, padded plaintext)
    for f in frames:
        if f.crc_status is CrcStatus.TRUNCATED or f.version != 2:
            continue
        method = f.encryption_method
        if method:
            scheme = f.security.encryption.scheme if f.security and f.security.encryption else None
            if scheme != "aes-gcm":
                encrypted[method].append(f)
        elif f.msgdef is not None and not f.incompat_flags & ~1 and f.crc_status is CrcStatus.OK:
            plain_ref.setdefault((f.sysid, f.msgid), (f.record, f.payload.ljust(f.msgdef.length, b"\x00")))
    for method, group in sorted(encrypted.items()):
        seqs: dict[tuple[int, bytes], set[tuple[int, int, int]]] = defaultdict(set)
        firsts: dict[tuple[int, bytes], int] = {}
        for f in group:
            k = (f.msgid, f.payload)
            seqs[k].add((f.sysid, f.compid, f.seq))
            firsts.setdefault(k, f.record)
        repeats = [f.record for f in group if len(seqs[(f.msgid, f.payload)]) > 1
                   and firsts[(f.msgid, f.payload)] != f.record]
        if repeats:
            names = sorted({f.msgname or str(f.msgid) for f in group if len(seqs[(f.msgid, f.payload)]) > 1})
            out.findings.append(Finding(
                "keystream-reuse", Severity.ERROR,
                f"method {method}: {len(repeats)} of {len(group)} encrypted frames repeat the ciphertext of an "
                f"earlier frame with another sequence number ({', '.join(names)}): every frame is encrypted with "
                f"the same keystream (frames {_frames_text(repeats)})", tuple(repeats)))
        # known plaintext: a plaintext frame of the same message from the same system, or a guess.
        # Each encrypted frame of that message gives a keystream candidate; a byte is trusted only where
        # every candidate agrees (the plaintext may vary between frames: a battery voltage does).
        best: tuple[bytes, Frame, str] | None = None  # (keystream prefix, frame it came from, source)
        guesses = dict(known)
        by_message: dict[tuple[int, int], list[Frame]] = defaultdict(list)
        for f in group:
            by_message[(f.sysid, f.msgid)].append(f)
        for (sysid, msgid), fs in sorted(by_message.items()):
            ref = plain_ref.get((sysid, msgid))
            if ref is not None:
                p, source = ref[1], f"the plaintext {fs[0].msgname} of frame {ref[0]}"
            elif msgid in guesses:
                p, source = guesses[msgid], f"the --known-plaintext {fs[0].msgname}"
            else:
                continue
            cands = [xor_bytes(f.payload[: len(p)], p[: len(f.payload)]) for f in fs]
            n = 0
            while all(len(c) > n for c in cands) and len({c[n] for c in cands}) == 1:
                n += 1
            if n and (best is None or n > len(best[0])):
                best = (cands[0][:n], fs[0], f"{source} ({len(fs)} frames agree)")
        if best is None:
            continue
        ks, from_frame, source = best
        from_record = from_frame.record
        recovered: list[int] = []
        for f in group:
            if f is from_frame:
                continue
            n = min(len(ks), len(f.payload))
            plain = xor_bytes(f.payload[:n], ks[:n])
            fields = None
            if n == len(f.payload) and f.msgdef is not None and n <= f.msgdef.length:
                fields = f.msgdef.decode(plain)
            out.recoveries.append(Recovery(f.record, f.msgname or str(f.msgid), plain, len(f.payload), fields))
            recovered.append(f.record)
        full = sum(1 for r in out.recoveries[-len(recovered):] if r.fields is not None) if recovered else 0
        out.findings.append(Finding(
            "keystream-reuse", Severity.ERROR,
            f"method {method}: keystream prefix of {len(ks)} bytes recovered from encrypted frame {from_record} "
            f"and {source}; "
            f"without the key, {len(recovered)} other encrypted frames are readable up to that length, "
            f"{full} of them completely", (from_record, *recovered)))
    return out


# --- summaries of the stage's verdicts -----------------------------------------------------------


def verdict_findings(frames: list[Frame]) -> list[Finding]:
    by: dict[str, list[int]] = defaultdict(list)
    keys_used: set[str] = set()
    no_cipher: list[int] = []
    failed: list[int] = []
    for f in frames:
        for n in f.notes:
            if n.code in ("key-leak", "unsigned-in-signed-stream", "nonce-reuse", "signature-skew"):
                by[n.code].append(f.record)
        sec = f.security
        if sec is None:
            continue
        if sec.signature_status is SignatureStatus.REPLAY:
            by["replay"].append(f.record)
        elif sec.signature_status is SignatureStatus.INVALID:
            by["sig-invalid"].append(f.record)
        if sec.key:
            keys_used.add(sec.key)
        enc = sec.encryption
        if enc is not None and enc.status is EncryptionStatus.NO_KEY:
            no_cipher.append(f.record)
        elif enc is not None and enc.status is EncryptionStatus.FAILED:
            failed.append(f.record)
    texts = {
        "key-leak": (Severity.ERROR, "SETUP_SIGNING sends the signing key in clear: whoever captured the link "
                                     "can sign frames (--use-leaked-keys verifies with it)"),
        "replay": (Severity.ERROR, "frames whose MAC verifies but whose timestamp is not newer than the last "
                                   "accepted one of their stream: replayed"),
        "sig-invalid": (Severity.ERROR, "signed frames that no supplied key verifies: forged, modified or "
                                        "signed with another key"),
        "unsigned-in-signed-stream": (Severity.WARN, "unsigned frames from senders that sign their frames "
                                                     "(a downgrade or an injection)"),
        "nonce-reuse": (Severity.ERROR, "aes-gcm nonces used twice under one key"),
        "signature-skew": (Severity.NOTE, "signing streams that start more than a minute from capture time "
                                          "(a receiver's new-stream check would refuse them)"),
    }
    findings = []
    for code, records in by.items():
        sev, text = texts[code]
        findings.append(Finding(code, sev, f"{len(records)} frame(s): {text} (frames {_frames_text(records)})",
                                tuple(records)))
    if failed:
        findings.append(Finding("decryption-failed", Severity.WARN,
                                f"{len(failed)} encrypted frame(s) did not decrypt with the configured cipher "
                                f"(frames {_frames_text(failed)})", tuple(failed)))
    if no_cipher:
        findings.append(Finding("encrypted-no-key", Severity.NOTE,
                                f"{len(no_cipher)} encrypted frame(s) without a cipher for their method "
                                f"(frames {_frames_text(no_cipher)})", tuple(no_cipher)))
    return findings


def audit(frames: list[Frame], *, words: list[bytes] | None = None, qgc: bool = False,
          known: list[tuple[int, bytes]] = ()) -> tuple[list[Finding], list[Recovery]]:  # type: ignore[assignment]
    findings = verdict_findings(frames)
    ks = keystream_audit(frames, list(known))
    findings += ks.findings
    if words is not None:
        findings += passphrase_findings(frames, words, qgc)
    return sort_findings(findings), ks.recoveries
