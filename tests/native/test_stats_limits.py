"""The analyses' limits, reached by the batches (native windows) as by the per-frame reference.

Each capture is made to go past one cap of the analyses: the copies ReplayedCommands remembers
(COPIES_KEPT, the newest but the one just seen forgotten), the senders Systems, ControlSources and
GnssAnomalies follow (every (sysid, compid) pair: more than the 4,096 they once followed), the channels of
one sender (MAX_CHANNELS) and in all (MAX_EXTRA), and, lowered for the test, the streams and conversations
StatsBuilder follows (MAX_STREAMS, MAX_CONVERSATIONS) and the sequence findings' counted names
(MAX_NAMED). The per-frame code is the reference (StatsBuilder.add, Expert.add); the batch code must give
its answers exactly at each cap, where a counter is fed per column and a cap is met per row.
"""

from __future__ import annotations

from collections.abc import Callable

import pytest

from mavscope.analysis import expert, stats
from mavscope.analysis.expert import COPIES_KEPT
from mavscope.analysis.framelist import MAX_FRAMES
from mavscope.analysis.sequence import MAX_CHANNELS, MAX_EXTRA
from mavscope.analysis.vehicles import MAX_SENDERS
from mavscope.mavlink.dialect import load_dialect
from tests.conftest import Cli
from tests.native import build as nh
from tests.native.engines import PURE, capture_file
from tests.native.stats_engines import native_stats_of, pure_stats
from tests.native.stories import BY_NAME, pack

pytest.importorskip("mavscope._native", reason="the native extension is not built (no compiler at install)")

DIALECT = load_dialect()
T0 = 1_700_000_000_000_000


def frame(name: str, values: dict[str, object], seq: int, sysid: int, compid: int) -> bytes:
    md = BY_NAME[name]
    return nh.frame_v2(md, md.id, pack(md, values), seq % 256, sysid, compid)


def check(data: bytes) -> dict[str, object]:
    with capture_file(data) as path:
        pure = pure_stats(path, DIALECT)
        native = native_stats_of(path, DIALECT)
    assert native == pure
    return pure


def test_copies_past_what_replayed_commands_remembers() -> None:
    """COPIES_KEPT + 2000 different COMMAND_LONGs (past the bound the newest remembered but the one just seen
    is forgotten), then copies out of the sender's sequence of forgotten and of remembered ones (forgotten
    and said: tests/analysis/test_replay_bounds.py)."""
    n = COPIES_KEPT + 2000
    frames = [frame("COMMAND_LONG", {"target_system": 1, "command": 511, "param1": float(i)}, i, 255, 190)
              for i in range(n)]
    entries = list(frames)
    entries.insert(1500, frames[2100])  # seen again: a copy? (its position tells) and remembered anew
    entries += [frames[5], frames[1999], frames[2100], frames[n - 3], frames[n - 300], frames[40_000]]
    data = nh.tlog([(T0 + i * 1000, f) for i, f in enumerate(entries)])
    with capture_file(data) as path:
        found = pure_stats(path, DIALECT)
        assert native_stats_of(path, DIALECT) == found
    codes = [f["code"] for f in found["findings"]]  # type: ignore[attr-defined]
    assert "replayed-command" in codes and "capacity" in codes


def test_more_senders_than_the_analyses_follow() -> None:
    """4,296 senders (past the 4,096 the analyses once followed; MAX_SENDERS is now every pair): HEARTBEATs of
    vehicles and GPS fixes (Systems, GnssAnomalies), then 17 armed vehicles each controlled by 255 others
    (ControlSources' intrusions, 4,335 (vehicle, sender) pairs)."""
    assert MAX_SENDERS == 256 * 256
    entries = []
    senders = [(s, c) for s in range(1, 256) for c in range(1, 256)][: 4096 + 200]
    for i, (s, c) in enumerate(senders):
        entries.append(frame("HEARTBEAT", {"type": 2, "autopilot": 3, "base_mode": 0x81, "custom_mode": 5},
                             i, s, c))
        for k, lat in enumerate((473977418, 474977418)):
            entries.append(frame("GPS_RAW_INT", {"time_usec": (1000 + k * 500) * 1000, "fix_type": 3, "lat": lat,
                                                 "lon": 85455939, "vel": 100, "satellites_visible": 12}, i, s, c))
    for vehicle in range(1, 18):
        entries.append(frame("HEARTBEAT", {"type": 2, "autopilot": 3, "base_mode": 0x81}, 1, vehicle, 1))
        entries.append(frame("COMMAND_LONG", {"target_system": vehicle, "command": 400, "param1": 1.0}, 1, 200, 1))
        for sysid in range(1, 256):
            entries.append(frame("RC_CHANNELS_OVERRIDE", {"target_system": vehicle}, vehicle, sysid, 190))
    data = nh.tlog([(T0 + i * 1000, f) for i, f in enumerate(entries)])
    found = check(data)
    codes = {f["code"] for f in found["findings"]}  # type: ignore[attr-defined,index]
    assert {"second-gcs-control", "gnss-position-jump"} <= codes


def test_commanders_sprayed_at_three_vehicles() -> None:
    """7,620 senders each command one of vehicles 1-3 (round robin): one `new-commander` finding per
    vehicle, whose count and first frames are worked out here from the list built (a sender is new when its
    system id is not the vehicle's first commander's, nor the vehicle's own); the same on both engines."""
    senders = [(s, c) for s in range(2, 256) for c in range(1, 31)]
    entries, first, new = [], {}, {}  # type: ignore[var-annotated]
    for i, (s, c) in enumerate(senders):
        target = 1 + i % 3
        entries.append(frame("COMMAND_LONG", {"target_system": target, "command": 400, "param1": 1.0}, i, s, c))
        if s == target:
            continue
        est = first.setdefault(target, (s, c))
        if est[0] != s:
            new.setdefault(target, []).append(len(entries))  # records count from 1
    found = check(nh.tlog([(T0 + i * 1000, f) for i, f in enumerate(entries)]))
    got = {int(f["message"].split()[4]): f for f in found["findings"]  # type: ignore[attr-defined,index]
           if f["code"] == "new-commander"}
    assert sorted(got) == [1, 2, 3]
    for target, records in new.items():
        assert got[target]["message"].startswith(f"{len(records)} senders command system {target} after "
                                                 f"{first[target][0]}/{first[target][1]},")
        assert got[target]["frames"] == records[:MAX_FRAMES]


def test_more_channels_than_the_sequence_counters_follow() -> None:
    """One sender on MAX_CHANNELS + 3 channels (the rest share one counter), then senders enough to pass
    MAX_EXTRA channels beyond their first in all."""
    records = []
    t = 1_700_000_000

    def udp(f: bytes, sport: int, dport: int, src: int = 1) -> None:
        nonlocal t
        t += 1
        ip = nh.ipv4(bytes([10, 0, 0, src]), bytes([10, 0, 1, 1]), 17, nh.udp(sport, dport, f))
        records.append((t, 0, nh.link("ethernet", ip, False)))

    for k in range(3):
        for ch in range(MAX_CHANNELS + 3):
            udp(frame("ATTITUDE", {}, k * 7 + ch, 1, 1), 14550 + ch, 14560)
    per = MAX_CHANNELS
    for s in range(MAX_EXTRA // (per - 1) + 2):
        for ch in range(per):
            udp(frame("ATTITUDE", {}, ch * 3, 2 + s // 250, s % 250), 20000 + ch, 14560, src=2 + s % 200)
    check(nh.pcap(records, nh.LINKTYPES["ethernet"]))


def test_a_dump_of_nothing() -> None:
    """A capture without frames: empty rows, totals of zero, no finding."""
    found = check(nh.pcap([(1_700_000_000, 0, b"\0" * 20)], nh.LINKTYPES["ethernet"]))
    assert found["json"]["totals"]["frames"] == 0  # type: ignore[index]
    assert found["findings"] == []


@pytest.fixture
def caps(monkeypatch: pytest.MonkeyPatch) -> Callable[..., None]:
    """Lowers the analyses' caps named (module attribute = value) for the test."""

    def lower(**values: int) -> None:
        for name, value in values.items():
            module = {"MAX_STREAMS": stats, "MAX_CONVERSATIONS": stats, "MAX_NAMED": expert}[name]
            monkeypatch.setattr(module, name, value)

    return lower


def test_more_streams_and_conversations_than_stats_follows(caps: Callable[..., None]) -> None:
    """MAX_STREAMS 5 and MAX_CONVERSATIONS 3: 4 senders x 2 messages from 4 UDP ports, twice. By hand: the
    first 5 (sender, message) streams are followed, the other 3 streams' frames (2 each) are unfollowed, 6;
    the first 3 endpoint pairs are followed, the fourth one's frames (2 a round) are unfollowed, 4."""
    caps(MAX_STREAMS=5, MAX_CONVERSATIONS=3)
    records = []
    for rnd in range(2):
        for sysid in range(1, 5):
            for k, name in enumerate(("HEARTBEAT", "ATTITUDE")):
                f = frame(name, {"type": 2, "autopilot": 3}, rnd * 2 + k, sysid, 1)
                ip = nh.ipv4(bytes([10, 0, 0, sysid]), bytes([10, 0, 1, 1]), 17, nh.udp(14550 + sysid, 14560, f))
                records.append((1_700_000_000 + len(records), 0, nh.link("ethernet", ip, False)))
    totals = check(nh.pcap(records, nh.LINKTYPES["ethernet"]))["json"]["totals"]  # type: ignore[index]
    assert (totals["unfollowed_stream_frames"], totals["unfollowed_conversation_frames"]) == (6, 4)


def test_more_named_messages_than_the_sequence_findings_keep(caps: Callable[..., None], cli: Cli) -> None:
    """MAX_NAMED 2: one sender's frames step back to 6 numbers seen (not one after the other: no restarted
    counter) with 3 messages, so the third is not named: "(... and more)", on both engines."""
    caps(MAX_NAMED=2)
    names = ("HEARTBEAT", "ATTITUDE", "SYS_STATUS")
    entries = [frame(names[i % 3], {}, i, 1, 1) for i in range(30)]
    entries += [frame(names[i % 3], {}, seq, 1, 1) for i, seq in enumerate((5, 3, 7, 1, 9, 2))]  # duplicates
    data = nh.tlog([(T0 + i * 1000, f) for i, f in enumerate(entries)])
    with capture_file(data) as path:
        assert native_stats_of(path, DIALECT) == pure_stats(path, DIALECT)
        pure = cli("stats", path, "--json", environ=PURE)
        native = cli("stats", path, "--json", environ={})
    assert native == pure
    assert "and more)" in pure.out
