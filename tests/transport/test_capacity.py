"""Bounds (issue 35, item 1; docs/security.md, "Bounds: what each gives up and how it is said"): every bounded
structure says what it gives up as a `capacity` note that `audit` reports, and a flood that reaches a bound gives
up its own entries, never the state established before it. One test per class of bound:

- young/established tiers (802.11 duplicate detection, TCP checksum directions);
- the newest given up (WPA2 handshakes begun, pending commands, parameter sets);
- memory held (802.11 fragments: expired, then the newest stations');
- oldest forgotten where that never hides a frame (relays: a second copy is shown).

Every expected count below is worked out by hand from the flood the test builds (comments say how); each test
fails under the old policy (least recent forgotten first), which flushed the genuine state.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from scapy.utils import wrpcap

from mavscope.analysis import command_log
from mavscope.capture.base import LINKTYPE_IEEE802_11_RADIOTAP, Record
from mavscope.notes import CODES, Note
from mavscope.transport import air
from mavscope.transport.air import Fragments, Relays
from mavscope.transport.decap import Decapsulator
from mavscope.transport.wpa import Wpa, wifi_key
from tests.support import wpa as w
from tests.transport.test_wifi_retry import AP, STA, frame

ROOT = Path(__file__).resolve().parents[2]


def capacity(notes: list[Note]) -> list[str]:
    return [n.message for n in notes if n.code == "capacity"]


def test_a_flood_of_new_transmitters_keeps_the_established_duplicate_cache(cli, tmp_path: Path,  # type: ignore[no-untyped-def]
                                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """STA sends 16 frames (sequence numbers 0-15: established, air.ESTABLISHED = 16); then 10 made-up
    transmitters send one frame each; then a forged retransmission of STA's number 15 with another body.
    With 20 numbers held at most: 16 + 4 flood frames fit, the flood's 5th to 10th frames each forget one young
    cache (6 give-ups, 1 number each), said at the 1st, 2nd and 4th: records 16 + 5, 16 + 6, 16 + 8. STA's
    cache is kept, so the forged repeat is the retry conflict the receiver discards (the old policy forgot STA's
    cache first and showed the forged frame)."""
    monkeypatch.setattr(air.Retries.__init__, "__defaults__", (20, None))
    assert air.ESTABLISHED == 16
    pkts = [frame(AP, STA, sn, sn) for sn in range(16)]
    pkts += [frame(AP, f"02:00:00:01:00:{i:02x}", 7, 100 + i) for i in range(10)]
    pkts.append(frame(AP, STA, 15, 99, retry=True))  # another MAVLink sequence number: another body
    pcap = tmp_path / "flood.pcap"
    wrpcap(str(pcap), pkts)
    status, out, _ = cli("audit", pcap, "--json")
    got = json.loads(out)["findings"]
    assert status == 1  # (findings of severity warn)
    by = {f["code"]: f for f in got}
    assert by["capacity"]["frames"] == [21, 22, 24]
    assert by["wifi-retry-conflict"]["frames"] == [27]
    frames = cli.jsonl(pcap)
    notes = {f["frame"]: [n["message"] for n in f.get("notes", ()) if n["code"] == "capacity"] for f in frames}
    assert "(4 given up so far, 4 sequence numbers)" in notes[24][0]
    assert 27 not in {f["frame"] for f in frames}  # the forged repeat is not shown as a frame
    for argv in (("audit", pcap), ("read", pcap, "-T", "jsonl")):
        assert cli(*argv, environ={"MAVSCOPE_PURE": "0"}) == cli(*argv, environ={"MAVSCOPE_PURE": "1"})


def test_a_flood_of_first_messages_between_message_1_and_2_gives_up_its_own() -> None:
    """The access point's message 1, then 9 forged message 1s from made-up stations, then the rest of the
    handshake and an encrypted frame, with 4 handshakes begun held at most. Pending: the genuine one, then
    flood frames 1-3 fit (4), flood frames 4-9 each give up the newest but themselves (6 give-ups), said at the
    1st, 2nd and 4th: flood frames 4, 5, 7 (records 5, 6, 8). The genuine handshake completes and its frame is
    decrypted (the old policy forgot it: the frame stayed 'wifi-undecoded')."""
    wpa = Wpa((wifi_key(f"wpa-pwd:{w.PASSPHRASE}:{w.SSID}", 1),), limit=4)
    dec = Decapsulator(wpa=wpa)
    hs = w.handshake()
    flood = [w.eapol_frame(f"02:00:00:00:01:{i:02x}", w.AP, w.eapol_key(0x008A, 1, w.ANONCE), i) for i in range(9)]
    pkts = [hs[0], *flood, *hs[1:], w.ccmp_frame(w.AP, w.STA, 3, 1, w.mavlink_packet(255, 0))]
    said: dict[int, list[str]] = {}
    for i, p in enumerate(pkts, 1):
        out = dec.feed(Record(i, float(i), LINKTYPE_IEEE802_11_RADIOTAP, bytes(p), 0, len(bytes(p))))
        said[i] = capacity([n for q in out for n in q.notes])
        last = out
    assert [r for r, m in said.items() if m] == [5, 6, 8]
    assert "(4 given up so far, 4 message 1s)" in said[8][0]
    assert last and last[0].data and not [n.code for n in last[0].notes]
    assert len(wpa.pairs) == 1


def test_a_flood_of_commands_does_not_call_the_waiting_arm_unanswered(monkeypatch: pytest.MonkeyPatch) -> None:
    """An ARM from 255/190 to 1/1 waits for its ACK; 5 commands from made-up senders follow; then the ACK.
    With 3 waiting at most: flood commands 1-2 fit, 3-5 each give up the newest waiting but themselves (3
    give-ups: flood commands 2, 3, 4), said at the 1st and 2nd. The ACK answers the ARM (the old policy gave the
    ARM up first: 'unanswered', its ACK an orphan)."""
    from mavscope.mavlink.dialect import load_dialect
    from tests.analysis.test_command_matcher import _feed

    monkeypatch.setattr(command_log, "PENDING_MAX", 3)
    m = command_log.CommandMatcher(load_dialect())
    _feed(m, ("cmd", "COMMAND_LONG", 400, (255, 190), (1, 1), 1))
    for i in range(5):
        _feed(m, ("cmd", "COMMAND_LONG", 400, (100 + i, 1), (1, 1), 2 + i))
    assert (m.given_up.count, len(m.given_up.said)) == (3, 2)
    _, done = _feed(m, ("ack", 400, (1, 1), 255, 190, 0, 7))
    assert [c.frames[0] for c in done] == [1] and m.orphan_count == 0


def test_a_flood_of_fragments_keeps_the_msdu_held_before_it() -> None:
    """Station S holds fragment 0 of an MSDU (100 bytes, air.FRAGMENT_COST = 256 besides: 356); 10 made-up
    stations then send fragment 0 of theirs (356 each); then S's last fragment. With 4 x 356 bytes held at most:
    S and flood stations 1-3 fit, flood stations 4-10 each drop the newest station's MSDU but their own (7
    give-ups, 7 x 356 bytes), said at the 1st, 2nd and 4th. S's MSDU completes (the old policy dropped S's,
    the least recent, first)."""
    assert air.FRAGMENT_COST == 256
    f = Fragments(limit=4 * 356)
    hdr = bytes(24)
    f.add(b"S" * 12, 0, 1 << 4, True, hdr, bytes(100), 1, 0.0)
    for i in range(10):
        f.add(bytes((i,)) * 12, 0, 1 << 4, True, hdr, bytes(100), 2 + i, 0.0)
    assert (f.given_up.count, f.given_up.units, len(f.given_up.said)) == (7, 7 * 356, 3)
    done = f.add(b"S" * 12, 0, (1 << 4) | 1, False, hdr, bytes(50), 12, 0.5).done
    assert done is not None and len(done[1]) == 150 and done[2] == (1,)


def test_a_forgotten_relay_is_said() -> None:
    """Relays forget the oldest (a forgotten one shows a second copy, never hides a frame): 5 frames sent to the
    access point with 2 remembered forget 3 (the 1st, 2nd and 3rd), said at the 1st and 2nd."""
    r = Relays(limit=2)
    for i in range(5):
        r.to_ap(b"a" * 6, b"b" * 6, bytes((i,)))
    assert (r.given_up.count, len(r.given_up.said)) == (3, 2)
    assert r.relayed(b"a" * 6, b"b" * 6, bytes((4,))) and not r.relayed(b"a" * 6, b"b" * 6, bytes((0,)))


# Every bound of mavscope's state (a module-level MAX_*, *_MAX, *_KEPT or *LIMIT constant), and how what it gives
# up is said: a registered code, or "-" with why nothing is given up (a listing, a resolution, an input
# refused as malformed). docs/security.md's table says the same. A new bound fails this test until it is here.
SAID: dict[str, str] = {
    "native/tables.py:_KEPT": "- a cache of compiled tables, built again",
    "analysis/objects/names.py:MAX_VEHICLE_PATH": "object-unsafe-path",
    "transport/air.py:MAX_REMEMBERED": "capacity",
    "transport/air.py:RELAYS_KEPT": "capacity",
    "transport/air.py:MAX_FRAGMENT_HELD": "capacity",
    "transport/wpa.py:MAX_PAIRS": "capacity",
    "transport/wpa.py:ANONCES_KEPT": "- message 1s per pair: the receiver keeps as few",
    "transport/wpa.py:KEYS_KEPT": "- keys per pair: a rekey replaces them",
    "transport/wpa.py:SEEN_KEPT": "- as KEYS_KEPT",
    "transport/decap.py:REBUILT_KEPT": "capacity",
    "transport/defrag.py:MAX_SOURCES": "capacity",
    "transport/defrag.py:MAX_HELD": "ip-fragment-dropped",
    "transport/defrag.py:MAX_DIST": "ip-fragment-dropped",
    "transport/defrag.py:MAX_DATAGRAM": "ip-fragment-dropped",
    "transport/defrag.py:RECORDS_KEPT": "- records a note names (all counted)",
    "transport/tcp.py:MAX_BUFFERED": "tcp-gap",
    "transport/tcp.py:MAX_TOTAL_BUFFERED": "tcp-gap",
    "transport/tcp.py:MAX_DIRECTIONS": "tcp-gap",
    "transport/tcp.py:ENDED_KEPT": "- ended streams' keys, for their framers' last bytes",
    "transport/tcp_direction.py:HOLES_KEPT": "tcp-late",
    "transport/ip.py:MAX_EXT_HEADERS": "malformed-packet",
    "transport/tunnel.py:MAX_DEPTH": "malformed-packet",
    "transport/wifi.py:MAX_PRESENT_WORDS": "malformed-packet",
    "transport/wifi.py:MAX_SUBFRAMES": "malformed-packet",
    "transport/ccmp.py:MAX_MPDU": "wifi-fragment",
    "capture/pcap.py:MIN_MAX_RECORD": "capture-garbage",
    "capture/pcapng.py:MAX_BLOCK": "capture-garbage",
    "capture/tlog.py:TEXT_MAX": "tlog-text",
    "capture/tlog.py:TS_MAX": "time-out-of-range",
    "pipeline/textrun.py:MAX_BYTES": "- a text run is reported and a new one starts",
    "mavlink/receivers.py:MAX_PER_PORT": "capacity",
    "mavlink/receivers.py:MAX_STATES": "capacity",
    "mavlink/receivers.py:MAX_MOVED": "capacity",
    "mavlink/receivers.py:MAX_OTHERS": "capacity",
    "pipeline/dissect.py:MAX_MAVLINK_ENDPOINTS": "capacity",
    "mavlink/dialect_cache.py:MAX_ENTRIES": "- a cache of parsed files",
    "mavlink/dialect_cache.py:MAX_ENTRY": "- as MAX_ENTRIES",
    "analysis/command_log.py:PENDING_MAX": "capacity",
    "analysis/command_log.py:ORPHANS_KEPT": "- listed, all counted",
    "analysis/stats.py:MAX_STREAMS": "- stats: unfollowed_stream_frames",
    "analysis/stats.py:MAX_CONVERSATIONS": "- stats: unfollowed_conversation_frames",
    "analysis/series.py:MAX_BUCKETS": "- resolution",
    "analysis/track.py:MAX_POINTS": "- resolution",
    "report/collect.py:MAX_VERDICT_CELLS": "- resolution (the report's signing slots double in width)",
    "report/geometry.py:MAX_MAP_POINTS": "- resolution (points drawn of a line; the JSON keeps every one)",
    "report/geometry.py:MAX_MAP_TRACKS": "- said on the page (features not drawn; the JSON keeps every one)",
    "report/geometry.py:MAX_MAP_SHAPES": "- said on the page (features not drawn; the JSON keeps every one)",
    "analysis/timeline.py:MAX_CLOCKS": "- timeline: unfollowed_readings",
    "analysis/params/tracker.py:MAX_COMPONENTS": "- params: limits.given_up",
    "analysis/params/tracker.py:MAX_NAMES": "- params: limits.given_up",
    "analysis/params/tracker.py:MAX_TIMELINE": "- params: limits.given_up",
    "analysis/params/tracker.py:MAX_PENDING": "- params: limits.given_up",
    "analysis/params/streams.py:MAX_KEYS": "- params: limits.given_up",
    "analysis/params/streams.py:KEPT": "- per key",
    "analysis/params/export.py:MAX_FINDINGS": "- listed, the rest summed",
    "analysis/params/pck.py:MAX_NAME": "- format",
    "analysis/objects/images.py:MAX_SENDERS": "object-limit",
    "analysis/objects/logs.py:SIZES_KEPT": "object-limit",
    "analysis/objects/names.py:MAX_COMPONENT": "- file names",
    "analysis/objects/tracker.py:MAX_LISTED": "- listed",
    "analysis/events/log.py:FIRST_KEPT": "capacity",
    "analysis/events/log.py:LAST_KEPT": "capacity",
    "analysis/events/log.py:MAX_EVENTS": "capacity",
    "analysis/events/log.py:MAX_CHATTER": "capacity",
    "analysis/events/statustext.py:MAX_OPEN": "- the text is shown, its end said not seen (end: limit)",
    "analysis/vehicles.py:MAX_SENDERS": "- every (system, component) pair: a table keyed by sender never fills",
    "analysis/gnss.py:MAX_EPISODES": "capacity",
    "analysis/timeline.py:PENDING_REQUESTS": "capacity",
    "analysis/expert.py:MAX_NAMED": "- an event's later messages not named, all counted",
    "analysis/expert.py:MAX_BURSTS": "capacity",
    "analysis/replays.py:COPIES_KEPT": "capacity",
    "analysis/crcextra.py:MAX_GROUPS": "capacity",
    "analysis/sequence.py:GAPS_KEPT": "- counted beyond",
    "analysis/sequence.py:MAX_CHANNELS": "- more channels share the sender's first counter",
    "analysis/sequence.py:MAX_EXTRA": "- as MAX_CHANNELS",
    "analysis/framelist.py:MAX_FRAMES": "- listed",
    "analysis/gnss.py:MAX_GAP_S": "- a time gap, no bound",
    "analysis/mission/answers.py:ANSWERED_KEPT": "- older clears' repeated ACKs shown as orphans",
    "analysis/mission/answers.py:MAX_FORKS": "- more answerers shown as orphans",
    "analysis/mission/model.py:OPEN_MAX": "capacity",
    "analysis/mission/answers.py:WAITING_MAX": "capacity",
    "analysis/mission/state.py:LISTED_MAX": "capacity",
    "security/keystream.py:ENCRYPTED_KEPT": "- the first looked at ",
    "security/verify.py:PROBLEMS_KEPT": "- listed, all counted",
    "security/passphrase.py:MAX_TARGETS": "- later streams not tried by --wordlist",
    "security/passphrase.py:MAX_WORD": "- wordlist input",
    "security/passphrase.py:MAX_NO_NEWLINE": "- wordlist input",
    "security/ciphers.py:MAX_PAYLOAD": "- format",
    "analysis/objects/imageformat.py:MAX_SIDE": "- no PNG written, the manifest says why (png_not_written)",
    "analysis/objects/images.py:MAX_LISTED": "- listed",
    "mavlink/floats.py:_CACHE_MAX": "- a memo, cleared",
    "native/table_blob.py:MAX_PAYLOAD": "- such a message is handed to the pure path",
    "rules/engine.py:MAX_KEYS": "capacity",
    "rules/engine.py:FRAMES_KEPT": "- listed, all counted",
    "rules/state.py:MAX_LINKS": "capacity",
    "rules/state.py:MAX_FIRST": "capacity",
    "rules/loader.py:MAX_FILE": "- a rule file the user gives: refused",
    "rules/loader.py:MAX_RULES": "- as MAX_FILE",
    "rules/loader.py:MAX_TEXT": "- as MAX_FILE",
    "rules/prefilter.py:MAX_RANGE": "- the rule is judged on every frame",
}
BOUND = re.compile(r"^((?:MAX|[A-Z0-9_]+_MAX|[A-Z0-9_]*_?KEPT|[A-Z0-9_]*LIMIT|MIN_MAX)[A-Z0-9_]*) *[:=]", re.M)
OUTSIDE = ("tui/", "output/", "commands/", "export/", "filter/", "fields/", "live/", "mavlink/dialect_check.py",
           "mavlink/dialect.py")


def test_every_bound_says_what_it_gives_up() -> None:
    """The bounds in the source are those of the table, and each says what it gives up with a registered code
    (or the table says why it gives nothing up). Front ends (tui, output, commands, export, filters) bound what
    they show, not the state a capture is judged on; dialect_check and dialect bound a dialect file they refuse."""
    found = set()
    for path in sorted((ROOT / "mavscope").rglob("*.py")):
        rel = path.relative_to(ROOT / "mavscope").as_posix()
        if rel.startswith(OUTSIDE):
            continue
        found |= {f"{rel}:{m}" for m in BOUND.findall(path.read_text())}
    assert sorted(found - SAID.keys()) == [], "a new bound: say what it gives up (docs/security.md, 'Bounds')"
    gone = [w for w in SAID if not re.search(rf"^{w.split(':')[1]} *[:=]",
                                             (ROOT / "mavscope" / w.split(":")[0]).read_text(), re.M)]
    assert gone == [], "a bound the table names is gone: take it out of the table"
    for where, code in SAID.items():
        assert code.startswith("- ") or code in CODES, where
        assert "helper" not in code, (where, "say what the bound gives up")
    assert CODES["capacity"].group.value == "capacity"
