"""Statistics: loss per link recovered from a capture with known frames removed, JSON keys, text."""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mavscope.analysis.sequence import SeqTracker
from mavscope.analysis.stats import RATE_BINS, compute_stats
from mavscope.capture.synth import udp_packet
from mavscope.mavlink.dialect import Dialect
from tests.conftest import CAPTURES, Cli
from tests.support import flows
from tests.support.builders import write_pcap, write_udp_pcap
from tests.support.captures import EXPECTED, frames, truth

LOSS = str(CAPTURES / "stats_loss.pcap")


def test_loss_per_link_matches_the_frames_removed(cli: Cli) -> None:
    doc = cli.json("stats", LOSS)
    links = {f"{lk['sysid']}/{lk['compid']}": lk for lk in doc["links"]}
    for key, t in truth("stats_loss.pcap")["links"].items():
        lk = links[key]
        assert lk["received"] == t["received"], key
        assert lk["lost"] == t["lost"], key
        assert lk["duplicates"] == t["duplicates"], key
        assert lk["crc"].get("bad", 0) == t["crc_bad"], key
        expected_pct = 100 * t["lost"] / (t["received"] - t["duplicates"] + t["lost"])
        assert lk["loss_pct"] == pytest.approx(expected_pct, abs=1e-3)
        assert lk["v2"] == lk["received"] and lk["v1"] == 0
    assert doc["totals"]["lost"] == sum(t["lost"] for t in truth("stats_loss.pcap")["links"].values())


def test_message_rates_and_keys(cli: Cli) -> None:
    doc = cli.json("stats", str(CAPTURES / "px4_sitl_udp.pcap"))
    assert {"messages", "links", "conversations", "totals", "findings"} <= set(doc)
    msgs = {(m["sysid"], m["compid"], m["msgname"]): m for m in doc["messages"]}
    att = msgs[(1, 1, "ATTITUDE")]
    assert {"sysid", "compid", "msgname", "count", "rate_hz", "bytes"} <= set(att)
    assert att["rate_hz"] == pytest.approx(10.0, rel=0.01)  # 100 ms period in the generator
    assert msgs[(1, 1, "HEARTBEAT")]["rate_hz"] == pytest.approx(1.0, rel=0.01)
    assert msgs[(1, 1, "HEARTBEAT")]["bytes"] == 21 * msgs[(1, 1, "HEARTBEAT")]["count"]
    assert sum(m["count"] for m in doc["messages"]) == EXPECTED["px4_sitl_udp.pcap"]["frames"]
    assert {(lk["sysid"], lk["compid"], lk["lost"]) for lk in doc["links"]} == {(1, 1, 0), (255, 190, 0)}
    conv = doc["conversations"]
    assert len(conv) == 1 and conv[0]["frames"] == EXPECTED["px4_sitl_udp.pcap"]["frames"]
    assert {conv[0]["a"], conv[0]["b"]} == {"127.0.0.1:14550", "127.0.0.1:14580"}
    assert conv[0]["duration"] == pytest.approx(60, abs=0.1)


def test_signature_totals_on_a_signed_capture(cli: Cli) -> None:
    doc = cli.json("stats", str(CAPTURES / "signed_udp.pcap"))
    assert doc["totals"]["signature"] == {"no-key": EXPECTED["signed_udp.pcap"]["signed"]}


def test_a_filter_selects_rows_computed_over_every_frame(cli: Cli) -> None:
    """Issue: `stats -Y HEARTBEAT` reported 96.9% loss on a healthy link (loss from HEARTBEATs alone)."""
    whole = {(lk["sysid"], lk["compid"]): lk for lk in cli.json("stats", LOSS)["links"]}
    doc = cli.json("stats", LOSS, "-Y", "HEARTBEAT")
    for lk in doc["links"]:
        assert lk == whole[(lk["sysid"], lk["compid"])]  # the same row, loss from every frame
    assert {m["msgname"] for m in doc["messages"]} == {"HEARTBEAT"}
    assert doc["filter"] == "HEARTBEAT" and 0 < doc["totals"]["matched"] < doc["totals"]["frames"]
    doc = cli.json("stats", LOSS, "-Y", "mavlink.sysid == 255")
    assert [(lk["sysid"], lk["lost"]) for lk in doc["links"]] == [(255, 2)]


def test_text_output_has_tables_and_sparklines(cli: Cli) -> None:
    status, out, err = cli("stats", LOSS)
    assert status == 0
    assert "Messages" in out and "Links" in out and "Conversations" in out and "Totals: 495 frames" in out
    assert any(ch in out for ch in "▁▂▃▄▅▆▇█")
    assert "\x1b[" not in out  # no colour when not a terminal


def test_a_burst_has_no_rate(cli: Cli, tmp_path: Path) -> None:
    """Issue: MISSION_CLEAR_ALL "2000.14 Hz" from 3 frames in a burst. Built here: 3 MISSION_CLEAR_ALL
    1 ms apart, 2 COMMAND_LONG 10 s apart, and HEARTBEAT at 1 Hz for 20 s."""
    gcs = flows.Sender(255, 190)
    entries = [(flows.T0 + i, gcs.pack(flows.heartbeat(gcs=True))) for i in range(20)]
    entries += [(flows.T0 + 5 + i * 0.001, gcs.pack(flows.v2.MAVLink_mission_clear_all_message(1, 1, 0)))
                for i in range(3)]
    entries += [(flows.T0 + 3 + 10 * i, gcs.pack(flows.command_long())) for i in range(2)]
    doc = cli.json("stats", flows.write_tlog(tmp_path, sorted(entries)))
    msgs = {m["msgname"]: m for m in doc["messages"]}
    assert (msgs["MISSION_CLEAR_ALL"]["rate_hz"], msgs["MISSION_CLEAR_ALL"]["burst"]) == (None, True)
    assert (msgs["COMMAND_LONG"]["rate_hz"], msgs["COMMAND_LONG"]["burst"]) == (None, False)  # 2 frames
    assert msgs["HEARTBEAT"]["rate_hz"] == pytest.approx(1.0) and not msgs["HEARTBEAT"]["burst"]
    status, out, _ = cli("stats", flows.write_tlog(tmp_path, sorted(entries), "b.tlog"))
    assert "burst" in out


def test_two_records_56_years_apart_keep_the_rate_series_bounded(cli: Cli, tmp_path: Path) -> None:
    """Issue: a 182-byte pcap whose records are 56 years apart built one entry per second of the span."""
    frame = flows.Sender(1, 1).pack(flows.heartbeat())
    packet = udp_packet("127.0.0.1", 14550, "127.0.0.1", 14550, frame)
    path = write_pcap(tmp_path / "far.pcap", [(sec, packet) for sec in (1, 56 * 365 * 86400)])
    status, out, err = cli("stats", str(path))
    assert status == 0 and "HEARTBEAT" in out, err
    stats = compute_stats(f for f in [])  # the histogram itself: at most RATE_BINS bins whatever the span
    from mavscope.analysis.stats import RateHistogram

    h = RateHistogram(0.0)
    h.add(0.0)
    h.add(56 * 365 * 86400.0)
    assert len(h.bins) <= RATE_BINS and sum(h.bins) == 2 and stats.frames == 0


@settings(max_examples=300, deadline=None)
@given(st.floats(0, 1e6), st.lists(st.floats(-10.0, 1e6), min_size=1, max_size=40))
def test_rate_histogram_counts_what_its_definition_counts(origin: float, offsets: list[float]) -> None:
    """By definition (RateHistogram's docstring): the final bin width W is the smallest power of two (from
    1 s) putting every frame in a bin below RATE_BINS, and bin i counts the frames with int((t - origin) / W)
    = i (0 for t <= origin). Worked out here from the times alone, not with the histogram's doubling; the
    stream may start late (no bins kept before its first frame's)."""
    from mavscope.analysis.stats import RateHistogram

    times = [origin + o for o in offsets]
    h = RateHistogram(origin)
    for t in times:
        h.add(t)
    w = 1.0
    while any(int((t - origin) / w) >= RATE_BINS for t in times if t > origin):
        w *= 2
    index = [int((t - origin) / w) if t > origin else 0 for t in times]
    want = [index.count(i) for i in range(max(index) + 1)]
    assert h.width == w
    assert [0] * h.start + h.bins == want + [0] * (h.start + len(h.bins) - len(want))
    assert h.start == min(index) and len(h.bins) <= max(index) - min(index) + 1
    span = max(times) - origin
    full = RateHistogram(origin)
    full.width, full.bins = w, want  # the same counts kept from bin 0 (as the native dump gives them)
    assert h.series(span, 12) == full.series(span, 12)


def test_seq_tracker_wrap_duplicates_and_late_frames() -> None:
    tr = SeqTracker()
    for s in [250, 251, 252, 255, 0, 1, 1, 3, 2, 5]:
        tr.feed(s)
    # lost 253, 254 (gap), 2 and 4 then 2 arrives late: lost = 2 + 1 + 1 - 1 = 3
    assert (tr.lost, tr.duplicates, tr.reordered) == (3, 1, 1)


def test_compute_stats_on_frames(dialect: Dialect) -> None:
    st = compute_stats(frames("px4_sitl_tcp.pcap", dialect))
    assert st.frames == EXPECTED["px4_sitl_tcp.pcap"]["frames"]
    assert st.conversations_json()[0]["transport"] == "tcp"


def test_signature_verdicts_with_the_key(cli: Cli) -> None:
    doc = cli.json("stats", str(CAPTURES / "signed_udp.pcap"), "--key", "passphrase:mavscope-demo",
                   "-Y", "signature.status == valid")
    assert doc["totals"]["signature"] == {"valid": EXPECTED["signed_udp.pcap"]["signed"]}


def test_a_seq_tracker_with_gaps_is_small() -> None:
    """A capture can make some 70,000 trackers (one per sender: 65,280 senders, and the expert's own), each
    with up to 127 missing slots: a hostile 6 MB tlog of HEARTBEATs from every sysid/compid with random
    sequence numbers took `stats` 1.1 GB while the slots were a dict (about 4 KB a tracker). Measured with
    tracemalloc (bytes allocated, not time): 2,000 trackers, each stepping by 10 (gaps of 9, small ones)
    three times round the counter, so that about 108 slots are missing at the end."""
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        trackers = []
        for _ in range(2000):
            tr = SeqTracker()
            for s in range(0, 256 * 3, 10):
                tr.feed(s % 256)
            tr.feed(240)  # late (8 behind the last, 248): fills a slot still missing
            trackers.append(tr)
        per_tracker = (tracemalloc.get_traced_memory()[0] - base) / len(trackers)
    finally:
        tracemalloc.stop()
    assert (trackers[0].lost, trackers[0].reordered, trackers[0].large_gaps) == (76 * 9 - 1, 1, 0)
    assert per_tracker < 1000, per_tracker


def test_seq_tracker_follows_a_restarted_counter() -> None:
    """A sender rebooting mid-capture: its counter restarts at 0 while the old one was at 100 (behind it:
    from 100 to 0 is 156 steps forward, so 0, 1, 2... step back without filling a gap)."""
    tr = SeqTracker()
    for s in list(range(50, 101)) + list(range(0, 40)):
        tr.feed(s)
    assert (tr.lost, tr.duplicates, tr.resets) == (0, 0, 1)


def test_seq_tracker_tells_an_uncounted_frame_from_a_copy() -> None:
    tr = SeqTracker()
    assert tr.feed(14, 1, b"a")[0] == "first"
    assert tr.feed(14, 2, b"b")[0] == "unchanged"  # same number, other bytes: the sender did not count it
    assert tr.feed(14, 3, b"b")[0] == "duplicate"  # a copy of the frame before
    assert tr.feed(14, 4)[0] == "duplicate"  # without the bytes nothing tells them apart
    assert (tr.unchanged, tr.duplicates, tr.lost) == (1, 2, 0)


def test_mavproxys_synthetic_param_values_are_neither_duplicates_nor_losses(cli: Cli, real_captures: Path) -> None:
    """ArduPlane SITL tlog: after its FTP parameter download MAVProxy wrote 1,435 PARAM_VALUE frames into the
    tlog under header 1/190, every one with seq 14 and its own parameter (MAVProxy's mavproxy_param.py
    log_params(); counted here with pymavlink: 1,435 frames, 1,434 repeats of the same seq, 1,435 distinct
    param_ids). Mission Planner (255/190) has 28 frames behind its counter that fill no gap
    (REQUEST_DATA_STREAM on a second counter) and 7 late ones: those stay duplicates/late."""
    from tests.support.pymavlink_reader import read

    path = real_captures / "ap_plane_sitl_mission3types_ftp_mp_mavproxy.tlog"
    if not path.is_file():
        pytest.skip(f"{path} is absent")
    synthetic = [m for m in read(path) if m.src == (1, 190)]
    assert len(synthetic) == 1435 and {m.name for m in synthetic} == {"PARAM_VALUE"}
    assert {m.msg.get_seq() for m in synthetic} == {14}
    assert len({m.msg.param_id for m in synthetic}) == 1435
    doc = cli.json("stats", path)
    links = {(lk["sysid"], lk["compid"]): lk for lk in doc["links"]}
    assert (links[(1, 190)]["received"], links[(1, 190)]["unchanged_seq"], links[(1, 190)]["duplicates"],
            links[(1, 190)]["lost"]) == (1435, 1434, 0, 0)
    assert (links[(255, 190)]["duplicates"], links[(255, 190)]["reordered"]) == (28, 7)
    codes = {(f["code"], f["message"].split(":")[0]) for f in doc["findings"]}
    assert ("seq-unchanged", "link 1/190") in codes and ("seq-duplicate", "link 1/190") not in codes


def test_seq_unchanged_says_what_was_seen(cli: Cli, real_captures: Path) -> None:
    """The gomavlib test vectors (PROVENANCE.md; read by pymavlink's parser here): two frames of 0/0, both seq 0,
    a HEARTBEAT and an OPTICAL_FLOW. The finding says so (one frame repeating its sender's number, with other
    contents) and names MAVProxy only as one known cause: no MAVProxy wrote them."""
    from tests.support.pymavlink_reader import read

    path = real_captures / "gomavlib_signed_testvectors_key4F_DERIVED.raw"
    msgs = read(path)
    assert [(m.src, m.msg.get_seq(), m.name) for m in msgs] == [((0, 0), 0, "HEARTBEAT"), ((0, 0), 0, "OPTICAL_FLOW")]
    [f] = [f for f in cli.json("stats", path)["findings"] if f["code"] == "seq-unchanged"]
    assert f["message"].startswith("link 0/0: 1 frame(s) repeat the sequence number of the frame before them from "
                                   "the same sender with other contents")
    assert "one known cause: MAVProxy" in f["message"] and f["frames"] == [2]


def test_seq_channels_are_per_endpoint_pair_and_bounded() -> None:
    """By hand: one sender numbering each channel from 0 repeats nothing per channel; beyond MAX_CHANNELS
    channels of one sender the rest share one counter, so state stays bounded whatever the input."""
    from types import SimpleNamespace

    from mavscope.analysis.sequence import MAX_CHANNELS, SeqChannels
    from mavscope.endpoint import Endpoint

    seqs = SeqChannels()
    dst = Endpoint("10.0.0.1", 14550)
    for port in range(MAX_CHANNELS + 5):
        for s in range(3):
            f = SimpleNamespace(sysid=255, compid=190, src=Endpoint("10.0.0.2", 20000 + port), dst=dst, seq=s,
                                record=0, raw=bytes([port, s]))
            seqs.feed(f)  # type: ignore[arg-type]  # the attributes a Frame has that the tracker reads
    chans = seqs.senders[(255, 190)]
    assert len(chans) == MAX_CHANNELS + 1 and ("*", "*") in chans
    t = seqs.totals((255, 190))
    # the first MAX_CHANNELS channels: 0, 1, 2 each, nothing repeated; the shared one sees 0, 1, 2 five times:
    # its first run is new; in each of the 4 runs after it, 0 and 1 step back behind the counter (at 2) and fill
    # nothing (duplicates), and 2 is the number of the frame before with other bytes (unchanged)
    assert sum(tr.duplicates + tr.unchanged for e, tr in chans.items() if e != ("*", "*")) == 0
    assert (t.lost, t.duplicates, t.unchanged) == (0, 4 * 2, 4)


def test_a_link_with_many_endpoints_lists_eight_in_its_cell(cli: Cli, tmp_path: Path) -> None:
    """One vehicle (1/1) sending a HEARTBEAT (pymavlink) from each of 12 UDP ports, 10.0.0.2:5001-5012:
    the JSON lists all 12, the text table's cell the first 8 in the JSON's order and "and 4 more" (a
    capture can give one link an endpoint per frame: rich wrapped a cell of 200,000 for 6 s)."""
    from tests.support.pmav import heartbeat, mav2

    packets = [(("10.0.0.2", 5001 + k), ("10.0.0.1", 14550), heartbeat(mav2(seq=k))) for k in range(12)]
    path = write_udp_pcap(tmp_path / "ports.pcap", packets, t0=1_700_000_000)
    [link] = cli.json("stats", path)["links"]
    assert sorted(link["endpoints"]) == sorted(f"10.0.0.2:{5001 + k}" for k in range(12))
    status, out, _ = cli("stats", path, environ={"COLUMNS": "400"})
    assert status == 0
    assert f"{', '.join(link['endpoints'][:8])} and 4 more (--json lists them)" in out
