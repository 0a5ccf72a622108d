"""Expert findings built from the frames of a capture (Wireshark's expert info, one level up).

`expert_findings(frames, dialect)` runs every detector in `DETECTORS` and returns their findings, most
severe first. Each detector is a plain function `(frames, dialect) -> list[Finding]`, so other layers
(the security audit, the TUI) can call one alone or add their own to the list. Finding codes are stable
(they appear in JSON); frame numbers are capture record numbers.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from mavscope.analysis.stats import SeqTracker
from mavscope.endpoint import Endpoint
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus, Frame, SignatureStatus, decode_payload
from mavscope.notes import Finding, finding, sort_findings

# Messages that tell a vehicle what to do (their target_system is the vehicle commanded).
COMMANDING = frozenset({
    "COMMAND_LONG", "COMMAND_INT", "SET_MODE", "MISSION_COUNT", "MISSION_CLEAR_ALL", "MISSION_SET_CURRENT",
    "MISSION_ITEM", "MISSION_ITEM_INT", "PARAM_SET", "PARAM_EXT_SET", "SET_POSITION_TARGET_LOCAL_NED",
    "SET_POSITION_TARGET_GLOBAL_INT", "SET_ATTITUDE_TARGET", "MANUAL_CONTROL", "RC_CHANNELS_OVERRIDE",
    "SETUP_SIGNING", "SET_HOME_POSITION", "SET_GPS_GLOBAL_ORIGIN", "FILE_TRANSFER_PROTOCOL",
})
MAV_TYPE_GCS = 6
BURST_MIN = 3  # bad-CRC frames...
BURST_WINDOW_S = 1.0  # ...each within this long of the previous one make a burst
GAP_MIN = 10  # a single sequence gap this large is reported
MAX_FRAMES = 50  # frame numbers listed per finding

Detector = Callable[[Sequence[Frame], Dialect], list[Finding]]


def _frames(nums: Sequence[int]) -> tuple[int, ...]:
    return tuple(dict.fromkeys(nums))[:MAX_FRAMES]


def _link(f: Frame) -> str:
    return f"{f.sysid}/{f.compid}"


def bad_crc_bursts(frames: Sequence[Frame], dialect: Dialect) -> list[Finding]:
    """Runs of bad-CRC frames close together: interference, a failing link, or injection attempts."""
    out: list[Finding] = []
    run: list[Frame] = []

    def close() -> None:
        if len(run) >= BURST_MIN:
            span = (run[-1].time - run[0].time) if run[0].time is not None and run[-1].time is not None else None
            when = f" within {span:.3f} s" if span is not None else ""
            links = ", ".join(sorted({_link(f) for f in run}))
            out.append(finding("bad-crc-burst", f"{len(run)} frames with a bad CRC{when} (links {links})",
                               _frames([f.record for f in run])))

    for f in frames:
        if f.crc_status is not CrcStatus.BAD:
            continue
        if run and not (f.time is not None and run[-1].time is not None and f.time - run[-1].time <= BURST_WINDOW_S):
            close()
            run = []
        run.append(f)
    close()
    return out


def sequence_anomalies(frames: Sequence[Frame], dialect: Dialect) -> list[Finding]:
    """Per link: large sequence gaps, duplicates, frames arriving late; many backward steps suggest two
    senders using the same system and component id."""
    trackers: dict[tuple[int, int], SeqTracker] = {}
    counts: dict[tuple[int, int], int] = {}
    events: dict[tuple[tuple[int, int], str], list[int]] = {}
    out: list[Finding] = []
    for f in frames:
        key = (f.sysid, f.compid)
        tr = trackers.get(key)
        if tr is None:
            tr = trackers[key] = SeqTracker()
        counts[key] = counts.get(key, 0) + 1
        prev = tr.last
        what, n = tr.feed(f.seq)
        if what == "gap" and n >= GAP_MIN:
            out.append(finding("seq-gap",
                               f"link {f.sysid}/{f.compid}: {n} frames lost (seq {prev} -> {f.seq})", (f.record,)))
        elif what in ("duplicate", "late"):
            events.setdefault((key, what), []).append(f.record)
    for (key, what), nums in events.items():
        sysid, compid = key
        if what == "duplicate":
            out.append(finding("seq-duplicate",
                               f"link {sysid}/{compid}: {len(nums)} frames repeat a sequence number already seen",
                               _frames(nums)))
        else:
            out.append(finding("seq-reordered",
                               f"link {sysid}/{compid}: {len(nums)} frames arrived after later ones", _frames(nums)))
    for key, total in counts.items():
        back = len(events.get((key, "duplicate"), ())) + len(events.get((key, "late"), ()))
        if back >= 5 and back * 20 >= total:
            out.append(finding("seq-interleaved",
                               f"link {key[0]}/{key[1]}: {back} of {total} frames step back in sequence: two senders "
                               "may share this system/component id",
                               _frames(events.get((key, "duplicate"), []) + events.get((key, "late"), []))))
    return out


def _command_frames(frames: Sequence[Frame]) -> list[tuple[Frame, dict[str, object]]]:
    out = []
    for f in frames:
        md = f.msgdef
        if md is None or md.name not in COMMANDING or f.crc_status is CrcStatus.BAD:
            continue
        fields = decode_payload(f)
        if fields is not None:
            out.append((f, fields))
    return out


def _gcs_systems(frames: Sequence[Frame]) -> set[int]:
    gcs = set()
    for f in frames:
        if f.msgid == 0 and f.msgdef is not None and f.msgdef.name == "HEARTBEAT":
            fields = decode_payload(f)
            if fields is not None and fields.get("type") == MAV_TYPE_GCS:
                gcs.add(f.sysid)
    return gcs


def command_sources(frames: Sequence[Frame], dialect: Dialect) -> list[Finding]:
    """Who commands each vehicle: a second system id commanding it (after the first), the same id
    commanding from another network endpoint, commands from a system that never sent a HEARTBEAT."""
    gcs = _gcs_systems(frames)
    heartbeat_seen: set[tuple[int, int]] = set()
    first_commander: dict[int, tuple[int, int]] = {}
    reported: set[tuple[str, object]] = set()
    endpoints: dict[tuple[int, int], Endpoint] = {}
    cmds = {id(f): fields for f, fields in _command_frames(frames)}
    out: list[Finding] = []
    for f in frames:
        if f.msgid == 0:
            heartbeat_seen.add((f.sysid, f.compid))
        fields = cmds.get(id(f))
        if fields is None:
            continue
        target = fields.get("target_system")
        if not isinstance(target, int) or target in gcs or target == f.sysid:
            continue
        sender = (f.sysid, f.compid)
        name = f.msgdef.name if f.msgdef else "?"
        est = first_commander.setdefault(target, sender)
        if est[0] != sender[0] and ("new", (target, sender)) not in reported:
            reported.add(("new", (target, sender)))
            out.append(finding("new-commander",
                               f"system {sender[0]}/{sender[1]} commands system {target} ({name}), which "
                               f"{est[0]}/{est[1]} commanded until then", (f.record,)))
        if f.src:
            known = endpoints.setdefault(sender, f.src)
            if known != f.src and ("src", (sender, f.src)) not in reported:
                reported.add(("src", (sender, f.src)))
                out.append(finding("unexpected-command-source",
                                   f"{name} from {sender[0]}/{sender[1]} arrives from {f.src}; its commands came "
                                   f"from {known} until then", (f.record,)))
        if sender not in heartbeat_seen and ("hb", sender) not in reported:
            reported.add(("hb", sender))
            out.append(finding("command-without-heartbeat",
                               f"{sender[0]}/{sender[1]} sends {name} to system {target} before any HEARTBEAT "
                               "of its own", (f.record,)))
    return out


def replayed_commands(frames: Sequence[Frame], dialect: Dialect) -> list[Finding]:
    """Commanding frames identical, byte for byte, to an earlier one and out of their sender's sequence
    (a retry has a new sequence number; a replay repeats an old one, where the same bytes coming back
    in sequence after the counter wrapped are not suspicious), and frames the security layer marked as
    replays."""
    seen: dict[bytes, Frame] = {}
    trackers: dict[tuple[int, int], SeqTracker] = {}
    out: list[Finding] = []
    for f in frames:
        tr = trackers.get((f.sysid, f.compid))
        if tr is None:
            tr = trackers[(f.sysid, f.compid)] = SeqTracker()
        step, _ = tr.feed(f.seq)
        sec = f.security
        if sec is not None and sec.signature_status is SignatureStatus.REPLAY:
            out.append(finding("replay", f"{f.msgname or f.msgid} from {_link(f)}: "
                               f"signature replay ({sec.reason_text or 'old timestamp'})",
                               (f.record,)))
            continue
        md = f.msgdef
        if md is None or md.name not in COMMANDING or f.crc_status is not CrcStatus.OK:
            continue
        prev = seen.get(f.raw)
        if prev is None or step not in ("duplicate", "late"):
            seen[f.raw] = f
            continue
        gap = f" {f.time - prev.time:.3f} s later" if f.time is not None and prev.time is not None else ""
        out.append(finding("replayed-command",
                           f"{md.name} from {_link(f)} is a byte-for-byte copy of frame {prev.record}{gap} "
                           "(same sequence number: a replay or a duplicated packet)", (prev.record, f.record)))
    return out


def unsigned_commands(frames: Sequence[Frame], dialect: Dialect) -> list[Finding]:
    """Unsigned commanding frames on a capture where the sender or its target signs: a downgrade."""
    signing: set[int] = {f.sysid for f in frames if f.signature is not None}
    if not signing:
        return []
    out: list[Finding] = []
    for f, fields in _command_frames(frames):
        if f.signature is not None:
            continue
        target = fields.get("target_system")
        if f.sysid in signing or target in signing:
            out.append(finding("unsigned-command",
                               f"unsigned {f.msgname} from {_link(f)} to system {target}, where signed traffic is seen",
                               (f.record,)))
    return out


def key_leaks(frames: Sequence[Frame], dialect: Dialect) -> list[Finding]:
    """SETUP_SIGNING carries the secret key in clear: whoever holds the capture holds the key."""
    nums = [f.record for f in frames if f.msgdef is not None and f.msgdef.name == "SETUP_SIGNING"]
    if not nums:
        return []
    return [finding("key-leak", f"{len(nums)} SETUP_SIGNING frame(s): the signing key travels in clear in this capture",
                    _frames(nums))]


DETECTORS: list[Detector] = [bad_crc_bursts, sequence_anomalies, command_sources, replayed_commands,
                             unsigned_commands, key_leaks]


def expert_findings(frames: Sequence[Frame], dialect: Dialect,
                    detectors: Sequence[Detector] | None = None) -> list[Finding]:
    """Every detector's findings, most severe first."""
    out: list[Finding] = []
    for detect in DETECTORS if detectors is None else detectors:
        out.extend(detect(frames, dialect))
    return sort_findings(out)
