"""Statistics: loss per link recovered from a capture with known frames removed, JSON keys, text."""

from __future__ import annotations

import pytest

from mavscope.analysis.stats import SeqTracker, compute_stats
from mavscope.mavlink.dialect import Dialect
from tests.conftest import CAPTURES, Cli
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


def test_filter_applies_before_statistics(cli: Cli) -> None:
    doc = cli.json("stats", LOSS, "-Y", "mavlink.sysid == 255")
    assert [(lk["sysid"], lk["lost"]) for lk in doc["links"]] == [(255, 2)]
    assert doc["filter"] == "mavlink.sysid == 255"


def test_text_output_has_tables_and_sparklines(cli: Cli) -> None:
    status, out, err = cli("stats", LOSS)
    assert status == 0
    assert "Messages" in out and "Links" in out and "Conversations" in out and "Totals: 495 frames" in out
    assert any(ch in out for ch in "▁▂▃▄▅▆▇█")
    assert "\x1b[" not in out  # no colour when not a terminal


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
