"""The one registry of expert information: every note (on a frame) and finding (on a capture).

Wireshark registers its expert info once per dissector (`ei_register_info`: a filter name, a group, a
severity and a summary); mavscope does the same here for everything it reports. A `Note` is attached
to one frame or record by the readers, the transport layer, the framer or the security stage; a
`Finding` is what an analysis concluded about a whole capture (statistics, missions, audits). Both
take their severity from the registered code, so one code means one severity everywhere, and codes
are a closed set: `note()` and `finding()` refuse an unregistered one. Codes are stable: they appear
in JSON output and in display filters (`note.bad-crc`).
"""

from __future__ import annotations

import operator
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from enum import Enum
from typing import TypeVar

K = TypeVar("K")
V = TypeVar("V")


def _by_rank(op: Callable[[int, int], bool]) -> Callable[[Severity, object], bool]:
    def compare(self: Severity, other: object) -> bool:
        if not isinstance(other, Severity):
            return NotImplemented
        return op(_RANK[self], _RANK[other])
    return compare


class Severity(str, Enum):
    """Wireshark's expert-info severities. They order by weight (CHAT < NOTE < WARN < ERROR), not by name."""

    CHAT = "chat"
    NOTE = "note"
    WARN = "warn"
    ERROR = "error"

    @property
    def rank(self) -> int:
        return _RANK[self]

    # str's comparisons would order the names; these order the weights
    __lt__ = _by_rank(operator.lt)
    __le__ = _by_rank(operator.le)
    __gt__ = _by_rank(operator.gt)
    __ge__ = _by_rank(operator.ge)


_RANK = {Severity.CHAT: 0, Severity.NOTE: 1, Severity.WARN: 2, Severity.ERROR: 3}


class Group(str, Enum):
    """What part of the data a code is about (Wireshark's expert groups)."""

    CAPTURE = "capture"  # the capture file itself
    MALFORMED = "malformed"  # a header or frame that does not parse
    REASSEMBLY = "reassembly"  # IP fragments, TCP streams
    CHECKSUM = "checksum"
    SEQUENCE = "sequence"  # MAVLink sequence numbers: loss, duplicates, reordering
    PROTOCOL = "protocol"  # a protocol exchange that is unusual (commands, missions)
    SECURITY = "security"  # signing, encryption, keys, injection, replay
    UNDECODED = "undecoded"  # what mavscope cannot decode (unknown link types, message ids)
    CAPACITY = "capacity"  # a bound of mavscope's own state gave something up (docs/security.md, "Bounds")


class Scope(str, Enum):
    FRAME = "frame"  # a Note on one frame or record
    CAPTURE = "capture"  # a Finding about the capture
    BOTH = "both"


@dataclass(frozen=True, slots=True)
class Code:
    """One registered code: its severity and group, a one-line summary, and for findings an explanation
    of what it means to the analyst (the sentence a finding message is built around)."""

    code: str
    severity: Severity
    group: Group
    scope: Scope
    summary: str
    explanation: str = ""

    @property
    def on_frames(self) -> bool:
        return self.scope is not Scope.CAPTURE


_F, _C, _B = Scope.FRAME, Scope.CAPTURE, Scope.BOTH
_CHAT, _NOTE, _WARN, _ERROR = Severity.CHAT, Severity.NOTE, Severity.WARN, Severity.ERROR

# Every code mavscope emits, grouped by the layer that emits it.
CODES: dict[str, Code] = {
    c.code: c
    for c in (
        # capture readers
        Code("record-truncated", _WARN, Group.CAPTURE, _F, "capture record shorter than its header says"),
        Code("record-snapped", _NOTE, Group.CAPTURE, _F, "record captured with fewer bytes than were on the wire"),
        Code("tlog-text", _NOTE, Group.UNDECODED, _F,
             "tlog entries that hold no MAVLink (a logger's console text or bytes it could not parse)"),
        Code("time-out-of-range", _WARN, Group.CAPTURE, _F,
             "record time before 1970 or after 9999 (as the file states it): reports show it as seconds"),
        Code("capture-garbage", _WARN, Group.CAPTURE, _F, "unparseable bytes in the capture file were skipped"),
        Code("unknown-linktype", _NOTE, Group.UNDECODED, _F, "link type mavscope does not decode"),
        Code("wifi-undecoded", _NOTE, Group.UNDECODED, _F,
             "802.11 data frame not decoded: encrypted (WPA2/WPA3) without a key for it"),
        Code("wifi-bad-fcs", _NOTE, Group.CHECKSUM, _F,
             "802.11 frame that failed its FCS check (the radio dropped it): not dissected"),
        Code("wifi-retry", _CHAT, Group.REASSEMBLY, _F,
             "802.11 retransmission the receiver discarded as a duplicate (Retry bit, same transmitter, "
             "sequence and fragment number): not dissected again"),
        Code("wifi-decrypt-failed", _WARN, Group.SECURITY, _B,
             "802.11 frame whose CCMP MIC fails under its station's key (the receiver drops it)",
             "WPA2 frames whose CCMP MIC fails under the key of the station pair they travel between, found from "
             "the 4-way handshake with the given --wifi-key: the receiver dropped them unread; a damaged frame, a "
             "frame under a key whose handshake the capture missed, or a forged one"),
        Code("wifi-replay", _WARN, Group.SECURITY, _B,
             "802.11 frame whose CCMP packet number is not above the last accepted (the receiver discards it)",
             "WPA2 frames that decrypt, but whose packet number is not above the last one their receiver accepted "
             "from the same transmitter and TID: the receiver discarded them as replays (a retransmission, which "
             "repeats its number, is told apart by its Retry bit first); a recorded frame sent again, as a "
             "replayed command would be"),
        Code("wifi-unprotected", _WARN, Group.SECURITY, _B,
             "802.11 data frame without protection between stations that have keys (the receiver drops it)",
             "802.11 data frames sent without protection between a station and its access point after their 4-way "
             "handshake gave them keys (or group-addressed from an access point that has a group key): a receiver "
             "drops every such frame but EAPOL, so their packets were shown to whoever captured them and never "
             "read by the vehicle; no station sends them: an injection"),
        Code("wifi-fragment", _WARN, Group.REASSEMBLY, _F,
             "802.11 fragments the receiver drops (none of their MSDU held before them, expired, pushed out, or never "
             "completed)"),
        Code("wifi-fragment-mixed", _WARN, Group.SECURITY, _B,
             "802.11 fragment mixing protection or keys into an MSDU, or skipping a packet number (dropped)",
             "802.11 fragments joined to an MSDU held for reassembly with another protection (plaintext among "
             "protected fragments), under another key, or with a packet number that is not the next: no radio sends "
             "these, and receivers drop them since the FragAttacks (2021), in which such fragments make a receiver "
             "read a packet an attacker put together; the MSDU they were sent into is read without them"),
        Code("wifi-relay", _CHAT, Group.REASSEMBLY, _F,
             "802.11 frame an access point relays (its packet was shown when a station sent it to the access point)"),
        Code("wifi-retry-conflict", _WARN, Group.SECURITY, _B,
             "802.11 retransmission with another body than its first copy (the receiver keeps the first)",
             "802.11 frames marked as retransmissions (the Retry bit, the transmitter's sequence number of the frame "
             "before) whose body differs from the frame they repeat: the receiver discarded them as duplicates and "
             "read the first, a monitor that takes the repeat sees other bytes; no radio does this by itself: a way "
             "to show a monitor another packet than the vehicle reads"),
        # transport
        Code("malformed-packet", _WARN, Group.MALFORMED, _F, "link, IP, UDP or TCP header is malformed"),
        Code("ip-fragment", _WARN, Group.REASSEMBLY, _F,
             "IP fragments that never made a whole datagram (the receiver discards them)"),
        Code("ip-fragment-dropped", _WARN, Group.REASSEMBLY, _F,
             "IP fragment or datagram the receiver's kernel drops (bad length, past the end, too far apart, "
             "too large, too many held)"),
        Code("ip-fragment-duplicate", _CHAT, Group.REASSEMBLY, _F, "IP fragment repeating bytes already held"),
        Code("ip-fragment-conflict", _WARN, Group.SECURITY, _B,
             "IP fragment repeating held bytes with other bytes (the receiver keeps the first)",
             "IP fragments that repeat bytes of their datagram with other bytes: Linux keeps the first and drops "
             "the repeat, other IP stacks and inspection tools may keep the repeat; no sender does this by "
             "itself: a way to show a monitor other bytes than the vehicle reads"),
        Code("ip-fragment-overlap", _WARN, Group.SECURITY, _B,
             "IP fragments overlapping: Linux discards the datagram, other stacks may read other bytes",
             "IP fragments that overlap others of their datagram partly: Linux discards the datagram (RFC 5722), "
             "other IP stacks and inspection tools may reassemble it with either fragment's bytes; no sender does "
             "this by itself: a way to make a monitor and a vehicle read different datagrams"),
        Code("ip-bad-checksum", _WARN, Group.CHECKSUM, _B,
             "IPv4 packet with a wrong header checksum (a receiver drops it before UDP or TCP reads it)",
             "IPv4 packets whose header checksum is wrong (0, which a sender that leaves it to its NIC shows, only "
             "on a TCP direction whose other checksums are right): every receiver drops them before UDP or TCP "
             "reads them, so their frames were shown to whoever captured them but not read by the vehicle (a TCP "
             "segment in one is left out of its stream where its direction's checksums are otherwise right)"),
        Code("udp-bad-checksum", _WARN, Group.CHECKSUM, _B,
             "UDP datagram with a wrong checksum (a receiver that checks drops it): its frames are shown",
             "UDP datagrams whose checksum is wrong (not a sender's offload placeholder): a receiver that checks "
             "them (Linux, most IP stacks) dropped them, so their frames were shown to whoever captured them but "
             "not read by the vehicle; a damaged link, a capture edited without fixing checksums, or an insertion"),
        Code("tcp-bad-checksum", _WARN, Group.CHECKSUM, _B,
             "TCP segment with a wrong checksum (a receiver that checks drops it)",
             "TCP segments whose checksum is wrong (a sender's offload placeholder too, on a direction whose other "
             "checksums are right): a receiver that checks them dropped them; where their direction has right "
             "checksums they are left out of the stream (the receiver's bytes, not the inserted ones), else read, "
             "as in a capture edited without fixing them"),
        Code("tcp-gap", _WARN, Group.REASSEMBLY, _F,
             "bytes missing from a TCP stream (the capture missed them, or a bound gave them up): read on after"),
        Code("tcp-late", _WARN, Group.REASSEMBLY, _F,
             "TCP bytes that came after their stream went on without them: read apart from the stream"),
        Code("tcp-retransmission", _CHAT, Group.REASSEMBLY, _F, "TCP retransmission dropped"),
        Code("tcp-conflict", _WARN, Group.SECURITY, _B,
             "TCP retransmission of delivered bytes with other bytes (the receiver keeps the first)",
             "TCP retransmissions that repeat bytes already delivered with other bytes: the receiving host keeps "
             "what it read first, a monitor that takes the retransmission sees other bytes; no TCP stack does "
             "this by itself: a way to show a monitor another stream than the vehicle reads"),
        Code("tcp-suspicious-syn", _WARN, Group.SECURITY, _F,
             "SYN with a new sequence number in an established TCP stream"),
        # framing
        Code("skipped-bytes", _WARN, Group.MALFORMED, _F, "bytes that are not MAVLink were skipped"),
        Code("truncated-frame", _WARN, Group.MALFORMED, _F, "frame cut short by the end of its packet or stream"),
        Code("bad-crc", _ERROR, Group.CHECKSUM, _F, "CRC does not match"),
        Code("unknown-msgid", _NOTE, Group.UNDECODED, _F, "message id not in the loaded dialects: CRC unchecked"),
        Code("length-mismatch", _WARN, Group.MALFORMED, _F, "payload length does not fit the message definition"),
        Code("unknown-incompat-flags", _WARN, Group.PROTOCOL, _F, "incompatibility flags mavscope does not know"),
        Code("char-after-nul", _NOTE, Group.SECURITY, _F,
             "a char array holds bytes after the NUL that ends its string (no reader shows them: garbage or a "
             "covert channel)"),
        Code("hidden-frame", _ERROR, Group.SECURITY, _B,
             "frame MAVLink's C library reads inside bytes the framer shows as other frames or skipped",
             "frames that MAVLink's C library (ArduPilot, PX4, QGroundControl) reads inside bytes the framer "
             "shows as other frames or skipped: inside frames it drops for unknown incompat flags (pymavlink and "
             "Wireshark show only those), or past damaged frames it reads whole: what a vehicle reads, hidden "
             "from length-based tools"),
        Code("split-frame", _WARN, Group.PROTOCOL, _B,
             "frame split over datagrams to one destination, which the receivers' parser reads whole",
             "frames split over UDP datagrams to one receiving socket: the vehicle's MAVLink parser (PX4, ArduPilot, "
             "QGroundControl keep one parser per socket) reads them whole, while tools that decode each datagram "
             "alone (pymavlink's per-datagram decoding, Wireshark) show a frame cut short and bytes that are not "
             "MAVLink: serial-to-UDP bridges split frames so, and an attacker can, to hide a command from them"),
        Code("encrypted-payload", _NOTE, Group.SECURITY, _F, "payload encrypted (incompat flag bits 5-7)"),
        # bounds of mavscope's own state, anywhere (docs/security.md, "Bounds: what each gives up and how it is said")
        Code("capacity", _WARN, Group.CAPACITY, _B,
             "a bound of mavscope's state gave something up (what, and how much so far)",
             "a bound of mavscope's own state (caches, waiting frames, streams, tables) gave something up: what "
             "and how much is said on the records where it did (read -Y note.capacity); a flood in the capture "
             "reaches these bounds, and what a bound gives up is the state that came last or was least "
             "established, never what was established before the flood"),
        # security stage (notes), and the audit's summaries of them (findings)
        Code("unsigned-in-signed-stream", _WARN, Group.SECURITY, _B,
             "unsigned frame from a sender that signs its frames",
             "unsigned frames from senders that sign their frames (a downgrade or an injection)"),
        Code("v1-in-signed-stream", _WARN, Group.SECURITY, _B,
             "MAVLink v1 frame from a sender that signs its frames (v1 cannot carry a signature)",
             "MAVLink v1 frames from senders that sign: the link takes frames that cannot be signed, so signing "
             "is not in force (a downgrade-capable link)"),
        Code("key-leak", _ERROR, Group.SECURITY, _B, "SETUP_SIGNING carries a signing key in clear",
             "SETUP_SIGNING sends the signing key in clear: whoever captured the link can sign frames "
             "(--use-leaked-keys verifies with it)"),
        Code("signature-skew", _NOTE, Group.SECURITY, _B, "new signing stream more than a minute from capture time",
             "signing streams that start more than a minute from capture time (a receiver's new-stream check "
             "would refuse them)"),
        Code("signature-ahead", _WARN, Group.SECURITY, _C,
             "a signing stream whose timestamps start far ahead of every other stream's: a receiver that takes "
             "it moves its signing clock that far ahead, so that genuine frames then look like replays to it "
             "(a future-timestamp attack), or that sender's clock is wrong"),
        Code("key-exchange", _NOTE, Group.SECURITY, _F, "MAVSCOPE_KEY_EXCHANGE public key (ECDH epoch)"),
        Code("nonce-reuse", _ERROR, Group.SECURITY, _B, "aes-gcm nonce used twice under one key",
             "aes-gcm nonces used twice under one key"),
        # expert findings over the frames (mavscope.analysis.expert)
        Code("bad-crc-burst", _WARN, Group.CHECKSUM, _C, "frames with a bad CRC close together"),
        Code("dialect-mismatch", _WARN, Group.SECURITY, _C,
             "bad-CRC frames of one sender and message id that all fit one other CRC_EXTRA: the sender defines "
             "the message otherwise (another dialect), and a receiver with its dialect reads frames hidden here"),
        Code("seq-gap", _WARN, Group.SEQUENCE, _C, "a large jump in a sender's sequence numbers: frames lost"),
        Code("seq-duplicate", _NOTE, Group.SEQUENCE, _C,
             "frames repeating a sequence number already seen on their channel"),
        Code("seq-unchanged", _NOTE, Group.SEQUENCE, _C,
             "frames from one sender repeating the previous frame's sequence number with other contents"),
        Code("seq-reordered", _NOTE, Group.SEQUENCE, _C, "frames filling a gap in sequence after later ones"),
        Code("seq-interleaved", _WARN, Group.SEQUENCE, _C,
             "many backward sequence steps on one channel: two senders may share a system/component id"),
        Code("seq-own-counter", _NOTE, Group.SEQUENCE, _C,
             "a ground station numbers REQUEST_DATA_STREAM on a counter of its own"),
        Code("seq-shared-counter", _NOTE, Group.SEQUENCE, _C,
             "several system/component ids number their frames on one counter: the numbers one skips, the "
             "others used"),
        Code("seq-logged-in-part", _NOTE, Group.SEQUENCE, _C,
             "a ground station's own frames in a tlog, which logs them only in part: the numbers missing from "
             "its sequence are not link loss",
             "a tlog records what the ground station that wrote it received; its own frames, and those of the "
             "ground stations it forwards (MAVProxy and Mission Planner, QGroundControl), are logged only in "
             "part: the sequence numbers missing from a ground station's frames (HEARTBEAT type GCS) in a tlog "
             "are not link loss, and are said in place of a seq-gap warning"),
        Code("new-commander", _WARN, Group.SECURITY, _C, "a second system commands a vehicle"),
        Code("unexpected-command-source", _WARN, Group.SECURITY, _C,
             "commands from a known sender arrive from another network endpoint"),
        Code("command-without-heartbeat", _NOTE, Group.PROTOCOL, _C, "commands from a system that sent no HEARTBEAT"),
        Code("replayed-command", _WARN, Group.SECURITY, _C,
             "a commanding frame repeats an earlier one byte for byte, out of its sender's sequence"),
        Code("unsigned-command", _WARN, Group.SECURITY, _C, "unsigned command where signed traffic is seen"),
        # control of a vehicle (mavscope.analysis.control)
        Code("second-gcs-control", _WARN, Group.SECURITY, _C,
             "control of an armed vehicle from a system other than the one in control",
             "a second ground station (or an attacker) sends manual control, modes or commands to an armed vehicle "
             "that another system controls: a takeover"),
        Code("unexpected-mode-change", _WARN, Group.SECURITY, _C,
             "a vehicle changed mode on the request of a system not in control"),
        Code("unexpected-mission-clear", _WARN, Group.SECURITY, _C,
             "a system not in control cleared a vehicle's mission"),
        Code("in-flight-disarm", _ERROR, Group.PROTOCOL, _C, "a vehicle disarmed while in the air"),
        # GNSS (mavscope.analysis.gnss)
        Code("gnss-position-jump", _WARN, Group.SECURITY, _C,
             "a position jump the reported velocity cannot explain (GNSS spoofing or a glitch)"),
        Code("gnss-fix-collapse", _WARN, Group.SECURITY, _C,
             "a GNSS fix or satellite count collapsing within seconds (jamming or obstruction)"),
        Code("ekf-gnss-alarm", _WARN, Group.SECURITY, _C,
             "the navigation filter reports a GPS glitch, lost position or failing innovation tests"),
        Code("gnss-time-jump", _WARN, Group.SECURITY, _C,
             "GNSS time stepping against the vehicle's boot clock or disagreeing with SYSTEM_TIME"),
        # objects moved over the link (mavscope.analysis.objects)
        Code("ftp-upload", _NOTE, Group.SECURITY, _C, "files written to a vehicle over MAVLink FTP"),
        Code("script-upload", _WARN, Group.SECURITY, _C, "a file the vehicle runs as code written over MAVLink FTP",
             "a file written where the vehicle runs it as code (an ArduPilot Lua script in APM/scripts, a PX4 "
             "etc/extras.txt or etc/rc.*): whoever can send FTP frames can run code on the vehicle"),
        Code("object-conflict", _WARN, Group.SECURITY, _C,
             "bytes of an object received twice with different values",
             "an object's bytes arrived twice with different values: a second sender (an injection) or damaged "
             "data; the first copy is kept"),
        Code("object-unsafe-path", _WARN, Group.SECURITY, _C,
             "a vehicle path that would leave the output directory, or holds NUL or control characters",
             "vehicle paths with '..' components, NUL or control characters, or of absurd length: a server does "
             "not send these by accident; the files are written under safe names"),
        Code("image-incomplete", _NOTE, Group.REASSEMBLY, _C, "images with ENCAPSULATED_DATA packets missing",
             "images sent as DATA_TRANSMISSION_HANDSHAKE and ENCAPSULATED_DATA whose packets the capture misses: "
             "their bytes are zeros in the files written, a raw image's missing rows zero rows in its PNG"),
        Code("image-format", _NOTE, Group.PROTOCOL, _C, "images whose bytes contradict their handshake's type",
             "images whose bytes (a file signature, or width x height bytes) are another format than their "
             "handshake's type names in common.xml: the older numbering of MAVLINK_DATA_STREAM_TYPE, from 1 "
             "(PX4FLOW's RAW8U is type 3), or a sender that says one format and sends another"),
        Code("object-limit", _WARN, Group.UNDECODED, _C, "a limit of the object reconstruction cut data",
             "the object reconstruction reached one of its limits (object size, memory, transfers at once, "
             "objects): what it gave up is listed"),
        # parameters (mavscope.analysis.params)
        Code("param-security-change", _WARN, Group.SECURITY, _C,
             "a security-relevant parameter (signing, system id checks, failsafes, fences, arming checks, "
             "scripting) was set or changed",
             "a parameter that guards the vehicle (MAVLink signing and system id checks, failsafes, fences, "
             "arming checks, scripting) was set or changed"),
        Code("param-protection-disabled", _ERROR, Group.SECURITY, _C,
             "a parameter change that turns a protection off",
             "a parameter change that turns a protection off (arming checks, a fence, a failsafe, system id "
             "enforcement) or makes a link accept unsigned frames"),
        # security audit (mavscope.security.audit)
        Code("replay", _ERROR, Group.SECURITY, _C, "signature replayed (timestamp not newer than its stream's)",
             "frames whose MAC verifies but whose timestamp is not newer than the last accepted one of their "
             "stream: replayed"),
        Code("sig-invalid", _ERROR, Group.SECURITY, _C, "signed frames that no supplied key verifies",
             "signed frames that no supplied key verifies: forged, modified or signed with another key"),
        Code("decryption-failed", _WARN, Group.SECURITY, _C, "encrypted frames that did not decrypt"),
        Code("encrypted-no-key", _NOTE, Group.SECURITY, _C, "encrypted frames without a cipher for their method"),
        Code("default-key", _ERROR, Group.SECURITY, _C, "frames signed with a well-known key (all zeros, ...)"),
        Code("weak-passphrase", _ERROR, Group.SECURITY, _C, "the signing passphrase is in the wordlist"),
        Code("rule", _WARN, Group.SECURITY, _C, "a detection rule matched (its own severity: docs/rules.md)"),
        Code("passphrase-not-found", _NOTE, Group.SECURITY, _C, "no word of the wordlist derives the signing key"),
        Code("keystream-reuse", _ERROR, Group.SECURITY, _C,
             "payload encryption reuses its keystream: payloads readable without the key"),
    )
}


def frame_codes() -> list[str]:
    """The codes a frame can carry as notes (the `note.*` filter fields)."""
    return [c.code for c in CODES.values() if c.on_frames]


@dataclass(frozen=True, slots=True)
class Note:
    """One annotation on a frame or record: a registered code, its severity, a message and the file offset."""

    code: str
    severity: Severity
    message: str
    offset: int | None = None

    def to_json(self) -> dict[str, object]:
        out: dict[str, object] = {"code": self.code, "severity": self.severity.value, "message": self.message}
        if self.offset is not None:
            out["offset"] = self.offset
        return out


def problem_line(where: str, n: Note) -> str:
    """A problem as `read` writes it on stderr: "WHERE: offset N: MESSAGE" (no offset when the message
    says it already). WHERE is "record R" for an anomaly, "frame F" for a frame's note."""
    offset = n.offset
    at = f"offset {offset}: " if offset is not None and f"offset {offset}" not in n.message else ""
    return f"{where}: {at}{n.message}"


def is_capture_damage(n: Note) -> bool:
    """Whether a frame's note tells of damage to the capture file (a cut record...): `read` reports those
    on stderr besides the anomalies, so that a damaged capture never passes in silence."""
    return CODES[n.code].group is Group.CAPTURE


def note(code: str, message: str | None = None, offset: int | None = None) -> Note:
    """A Note for a registered code (KeyError for an unregistered one: codes are a closed set)."""
    c = CODES[code]
    return Note(code, c.severity, message if message is not None else c.summary, offset)


@dataclass(frozen=True, slots=True)
class Finding:
    """What an analysis concluded about a capture, with the frames involved (Wireshark's frame numbers)."""

    code: str
    severity: Severity
    message: str
    frames: tuple[int, ...] = ()
    rule: str | None = None  # a detection rule's id (code `rule`: mavscope.rules), shown as `rule` in JSON

    def to_json(self) -> dict[str, object]:
        return {"code": self.code, "severity": self.severity.value, "frames": list(self.frames),
                "message": self.message, **({"rule": self.rule} if self.rule is not None else {})}


class FrameNumbers:
    """The frames behind a finding as it accumulates: every one counted, the first `limit` kept (with
    `repeats=False`, a number added twice in a row kept once), so a finding over millions of frames stays
    small."""

    __slots__ = ("nums", "count", "limit", "repeats")

    def __init__(self, limit: int, repeats: bool = False) -> None:
        self.nums: list[int] = []
        self.count = 0
        self.limit = limit
        self.repeats = repeats

    def add(self, number: int) -> None:
        self.count += 1
        nums = self.nums
        if len(nums) < self.limit and (self.repeats or not nums or nums[-1] != number):
            nums.append(number)


class GivenUp:
    """What one bounded structure gave up, said as `capacity` notes (docs/security.md, "Bounds"): every give-up
    counted, with the units it gave up (records, numbers, bytes); the 1st, 2nd, 4th, 8th... said, each with
    the counts so far (a flood is not noted one by one), onto `said`, a list the layer that owns the
    structure empties onto the record being read. An analysis's bound, which notes no frame, says the same as
    one `capacity` finding (`finding()`), with the records where those give-ups came."""

    __slots__ = ("what", "unit", "count", "units", "said", "records", "detail")

    def __init__(self, what: str, unit: str, said: list[Note] | None = None) -> None:
        self.what = what  # the structure and its bound, e.g. "802.11 duplicate detection (262,144 numbers)"
        self.unit = unit  # what `units` counts, e.g. "sequence numbers"
        self.count = 0
        self.units = 0
        self.said: list[Note] = [] if said is None else said
        self.records: list[int] = []  # the records of the give-ups said (those `add` was given one for)
        self.detail = ""  # the last give-up said

    def add(self, detail: str, units: int = 1, record: int | None = None) -> None:
        """One give-up of `units` (`detail`: what went, and what that means to the analyst; `record`: the
        record that made the bound give it up, for `finding`)."""
        self.count += 1
        self.units += units
        if not self.count & (self.count - 1):
            self.detail = detail
            self.said.append(note("capacity", f"{self.what}: {detail} ({self.count:,} given up so far, "
                                  f"{self.units:,} {self.unit})"))
            if record is not None:
                self.records.append(record)

    def finding(self) -> Finding | None:
        """The `capacity` finding of what this bound gave up (None when nothing): how much, the last give-up
        said, and the records where the 1st, 2nd, 4th... came."""
        if not self.count:
            return None
        return finding("capacity", f"{self.what}: {self.count:,} given up ({self.units:,} {self.unit}); the last "
                                   f"said: {self.detail}", self.records)


def pop_newest(table: dict[K, V], keep: object) -> tuple[K, V]:
    """The house policy where a flood must not flush established state: take out the newest entry of `table`
    (insertion order, as an OrderedDict's LRU order) other than `keep` (the one just added). A flood then
    churns its own entries; what was there before it stays."""
    it = reversed(table)
    k = next(it)
    if k == keep:
        k = next(it)
    return k, table.pop(k)


def finding(code: str, message: str, frames: Iterable[int] = ()) -> Finding:
    """A Finding for a registered code, with the code's severity (KeyError for an unregistered one)."""
    return Finding(code, CODES[code].severity, message, tuple(frames))


FRAMES_SHOWN = 8  # frame numbers a finding's text line lists (--json lists them all)


def finding_line(f: Finding) -> str:
    """A finding as one line of text: "[SEVERITY] CODE: MESSAGE (frames 1, 2, 3 and 5 more)", its frames from
    `Finding.frames` (a message never lists them: this is the one place they are written as text)."""
    nums = f.frames
    shown = ", ".join(map(str, nums[:FRAMES_SHOWN])) + (f" and {len(nums) - FRAMES_SHOWN} more"
                                                         if len(nums) > FRAMES_SHOWN else "")
    code = f"{f.code} {f.rule}" if f.rule else f.code  # a rule's finding: "rule ID"
    return f"[{f.severity.value}] {code}: {f.message}" + (f" (frames {shown})" if nums else "")


def explanation(code: str) -> str:
    """What a code means to the analyst (its summary where no longer explanation is registered)."""
    c = CODES[code]
    return c.explanation or c.summary


def sort_findings(findings: Iterable[Finding]) -> list[Finding]:
    """Most severe first, then by first frame, then by code."""
    return sorted(findings, key=lambda f: (-f.severity.rank, f.frames[:1], f.code))
