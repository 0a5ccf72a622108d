"""`mavscope audit`: summaries of the security stage's verdicts, with the keystream and passphrase audits.

Everything here returns `Finding`s from the one registry (`mavscope.notes`), whose explanations are the
sentences the summaries are built around; presentation is the command's job.
"""

from __future__ import annotations

from collections import defaultdict

from mavscope.mavlink.frame import EncryptionStatus, Frame, SignatureStatus
from mavscope.notes import Finding, explanation, finding, sort_findings
from mavscope.security.keystream import Recovery, frames_text, keystream_audit
from mavscope.security.passphrase import passphrase_findings

# The notes of the security stage that the audit sums up, in the order it reports them first.
_NOTE_CODES = ("key-leak", "unsigned-in-signed-stream", "nonce-reuse", "signature-skew")


def verdict_findings(frames: list[Frame]) -> list[Finding]:
    """One finding per kind of verdict the security stage gave (with every frame that got it)."""
    by: dict[str, list[int]] = defaultdict(list)
    no_cipher: list[int] = []
    failed: list[int] = []
    for f in frames:
        for n in f.notes:
            if n.code in _NOTE_CODES:
                by[n.code].append(f.record)
        sec = f.security
        if sec is None:
            continue
        if sec.signature_status is SignatureStatus.REPLAY:
            by["replay"].append(f.record)
        elif sec.signature_status is SignatureStatus.INVALID:
            by["sig-invalid"].append(f.record)
        enc = sec.encryption
        if enc is not None and enc.status is EncryptionStatus.NO_KEY:
            no_cipher.append(f.record)
        elif enc is not None and enc.status is EncryptionStatus.FAILED:
            failed.append(f.record)
    findings = [finding(code, f"{len(records)} frame(s): {explanation(code)} (frames {frames_text(records)})",
                        records) for code, records in by.items()]
    if failed:
        findings.append(finding("decryption-failed",
                                f"{len(failed)} encrypted frame(s) did not decrypt with the configured cipher "
                                f"(frames {frames_text(failed)})", failed))
    if no_cipher:
        findings.append(finding("encrypted-no-key",
                                f"{len(no_cipher)} encrypted frame(s) without a cipher for their method "
                                f"(frames {frames_text(no_cipher)})", no_cipher))
    return findings


def audit(frames: list[Frame], *, words: list[bytes] | None = None, qgc: bool = False,
          known: tuple[tuple[int, bytes], ...] = ()) -> tuple[list[Finding], list[Recovery]]:
    """Every security finding of the capture, most severe first, and the payloads recovered without a key."""
    findings = verdict_findings(frames)
    ks = keystream_audit(frames, list(known))
    findings += ks.findings
    if words is not None:
        findings += passphrase_findings(frames, words, qgc)
    return sort_findings(findings), ks.recoveries
