"""`mavscope audit`: summaries of the security stage's verdicts, with the keystream and passphrase audits.

Everything here returns `Finding`s from the one registry (`mavscope.notes`), whose explanations are the
sentences the summaries are built around; presentation is the command's job. `Audit` takes the frames
one at a time and keeps bounded state (frame numbers listed up to a cap, all counted), so a capture of
any length is audited without holding its frames.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable

from mavscope.mavlink.frame import EncryptionStatus, Frame, SignatureStatus
from mavscope.notes import Finding, FrameNumbers, Note, explanation, finding, sort_findings
from mavscope.pipeline.dissect import Anomaly
from mavscope.security.downgrade import Judged
from mavscope.security.keystream import DAMAGED, Collector, Recovery, keystream_audit
from mavscope.security.passphrase import Stream, Targets, default_key_findings, passphrase_findings
from mavscope.security.signing import NEW_STREAM_WINDOW

# The notes of the security stage that the audit sums up, in the order it reports them first.
_NOTE_CODES = ("key-leak", "hidden-frame", "split-frame", "unsigned-in-signed-stream", "v1-in-signed-stream",
               "nonce-reuse", "signature-skew", "ip-fragment-overlap", "ip-fragment-conflict", "tcp-conflict",
               "wifi-retry-conflict", "wifi-fragment-mixed", "wifi-unprotected", "wifi-replay", "wifi-decrypt-failed",
               "ip-bad-checksum", "tcp-bad-checksum", "udp-bad-checksum", "capacity")
RECORDS_LISTED = 10_000  # frame numbers kept per kind of verdict (all of them are counted)
AHEAD_S = 3600.0  # a signing stream that starts this much further ahead of the capture clock than every other


def _records() -> FrameNumbers:
    """Frame numbers of one kind of verdict: the first RECORDS_LISTED, and the count."""
    return FrameNumbers(RECORDS_LISTED, repeats=True)


class Audit:
    """`audit` in one pass: `add(frame)` per frame in capture order (bounded state), then `result()`."""

    def __init__(self) -> None:
        self.by: dict[str, FrameNumbers] = defaultdict(_records)
        self.no_cipher = _records()
        self.failed = _records()
        self.keystreams = Collector()
        self.targets = Targets()

    def add(self, f: Frame) -> None:
        self.add_untargeted(f)
        self.targets.add(f)

    def anomaly(self, item: Anomaly) -> None:
        """A record's notes that belong to no frame (the IP fragments that disagree, for one)."""
        self._notes(item.record, item.notes)

    def _notes(self, record: int, notes: tuple[Note, ...]) -> None:
        for n in notes:
            if n.code in _NOTE_CODES:
                self.by[n.code].add(record)

    def add_untargeted(self, f: Frame) -> None:
        """Everything `add` does but the signing streams' target frames (`Targets`), which a caller that
        counts signed frames in bulk (the export's native source) gives `targets` itself."""
        self._notes(f.record, f.notes)
        self.keystreams.add(f)
        sec = f.security
        if sec is None:
            return
        if sec.signature_status is SignatureStatus.REPLAY:
            self.by["replay"].add(f.record)
        elif sec.signature_status is SignatureStatus.INVALID:
            self.by["sig-invalid"].add(f.record)
        enc = sec.encryption
        if f.crc_status in DAMAGED:
            # incompat bits 5-7 on a damaged frame are as likely a flipped bit as encryption (the CRC covers
            # the ciphertext: an encrypted frame that arrived whole checks): no encryption finding from it
            return
        if enc is not None and enc.status is EncryptionStatus.NO_KEY:
            self.no_cipher.add(f.record)
        elif enc is not None and enc.status is EncryptionStatus.FAILED:
            self.failed.add(f.record)

    def early(self, judged: Iterable[Judged]) -> None:
        """The unsigned frames of signing senders that came before their first signed frame (Downgrades, at
        the end of the capture): counted with the stage's notes of the same codes, in frame order."""
        for j in judged:
            for code, count, listed in (("unsigned-in-signed-stream", j.v2, j.listed_v2),
                                        ("v1-in-signed-stream", j.v1, j.listed_v1)):
                if not count:
                    continue
                r = self.by[code]
                merged = sorted(r.nums + [rec for rec, _, _ in listed])
                r.nums = merged[:r.limit]
                r.count += count

    def verdict_findings(self) -> list[Finding]:
        """One finding per kind of verdict the security stage gave (with the frames that got it)."""
        findings = [finding(code, f"{r.count} frame(s): {explanation(code)}", r.nums)
                    for code, r in self.by.items()]
        if self.failed.count:
            findings.append(finding("decryption-failed",
                                    f"{self.failed.count} encrypted frame(s) did not decrypt with the configured "
                                    "cipher", self.failed.nums))
        if self.no_cipher.count:
            findings.append(finding("encrypted-no-key",
                                    f"{self.no_cipher.count} encrypted frame(s) without a cipher for their method",
                                    self.no_cipher.nums))
        return findings

    def result(self, *, words: Iterable[bytes] | None = None, qgc: bool = False,
               known: Iterable[tuple[int, bytes]] = (),
               early: Iterable[Judged] = ()) -> tuple[list[Finding], list[Recovery]]:
        """Every security finding, most severe first, and the payloads recovered without a key (`early`:
        the unsigned frames of signing senders before their first signed frame, `Downgrades.judged()`)."""
        self.early(early)
        findings = self.verdict_findings()
        ks = keystream_audit(self.keystreams, known)
        findings += ks.findings
        findings += default_key_findings(self.targets.frames)
        findings += ahead_findings(self.targets.frames)
        if words is not None:
            findings += passphrase_findings(self.targets.frames, words, qgc)
        return sort_findings(findings), ks.recoveries


def ahead_findings(streams: dict[Stream, list[Frame]]) -> list[Finding]:
    """`signature-ahead`: signing streams whose first frame's signature time (the timestamp is in clear: no
    key needed) is more than a minute ahead of the capture clock and AHEAD_S further ahead than the first
    frame of every other signing stream in the capture. Comparing streams with each other, not with the
    capture clock alone, keeps a capture taken with a wrong clock quiet; with one stream nothing is said.
    `streams`: each stream's target frames (`Targets.frames`), its first signed frame with a good CRC first."""
    starts: dict[Stream, tuple[Frame, float]] = {}
    for stream, fs in streams.items():
        first = fs[0] if fs else None
        if first is not None and first.signature is not None and first.time is not None:
            starts[stream] = (first, first.signature.unix_time - first.time)
    out: list[Finding] = []
    for (sysid, compid, link), (f, skew) in sorted(starts.items()):
        others = [k for s, (_, k) in starts.items() if s != (sysid, compid, link)]
        if not others or skew <= NEW_STREAM_WINDOW or skew - max(others) <= AHEAD_S:
            continue
        out.append(finding(
            "signature-ahead",
            f"{sysid}/{compid} signature link {link}: its signing stream starts {skew:+,.0f} s from the capture clock "
            f"({skew / 86400:.1f} days ahead), {skew - max(others):,.0f} s ahead of every other signing stream of "
            f"the capture (the nearest {max(others):+,.1f} s): a receiver that takes it moves its signing clock "
            f"that far ahead, so that genuine frames then look like replays to it (a future-timestamp attack), or "
            f"that sender's clock is wrong (frame {f.record})", [f.record]))
    return out


def audit(frames: Iterable[Frame], *, words: Iterable[bytes] | None = None, qgc: bool = False,
          known: Iterable[tuple[int, bytes]] = ()) -> tuple[list[Finding], list[Recovery]]:
    """Every security finding of `frames`, most severe first, and the payloads recovered without a key."""
    a = Audit()
    for f in frames:
        a.add(f)
    return a.result(words=words, qgc=qgc, known=known)
