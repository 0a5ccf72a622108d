"""Loss figures of ground stations in tlogs are explained, not alarming (issue 35, item 15).

A tlog is written by a ground station program (QGroundControl, Mission Planner, MAVProxy, BlueOS): it
records what that program received, and its own frames (and those of the ground stations it forwards) only
in part, so the sequence numbers missing from a ground station's frames there are not link loss. mavscope
marks those links in `stats` (`logged_in_part`, the `*` line, the totals said apart) and says
`seq-logged-in-part` (a note) in place of a `seq-gap` warning. Captured on the wire, the same frames' gaps
are link loss (tests/analysis/test_expert.py).

Expected answers, read without mavscope: the ground stations are the systems that sent a HEARTBEAT of type
MAV_TYPE_GCS (6) as pymavlink decodes the tlog record by record (tests/support/pymavlink_reader.py); each
sender's missing numbers are counted here from the frames' sequence numbers (a step ahead by d < 128 skips
d - 1; a frame behind by less than 128 that lands on a skipped number fills it), the rule common.xml's
8-bit counter and docs/analysis.md give.
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import pytest

from tests.conftest import Cli
from tests.support import flows
from tests.support.pymavlink_reader import header, read

MAV_TYPE_GCS = 6
PURE = {"MAVSCOPE_PURE": "1"}


def _missing(seqs: list[int]) -> int:
    """Numbers skipped by a sender's 8-bit counter that no late frame filled."""
    top, pos, lost = seqs[0], 0, 0
    skipped: set[int] = set()  # positions (unwrapped) skipped, while less than 128 behind the newest
    for s in seqs[1:]:
        d = (s - top) % 256
        if d == 0:
            continue
        if d < 128:
            skipped.update(pos + k for k in range(1, d))
            lost += d - 1
            pos, top = pos + d, s
            skipped = {p for p in skipped if pos - p < 128}
        elif (p := pos - (256 - d)) in skipped:
            skipped.discard(p)
            lost -= 1
    return lost


def _link(f: dict) -> str:
    return f["message"].removeprefix("link ").split(":")[0]


def _tlogs() -> list[str]:
    from tests.conftest import REAL_CAPTURES

    return sorted(p.name for p in REAL_CAPTURES.glob("*.tlog")) or ["(no real captures)"]


@pytest.mark.parametrize("name", _tlogs())
def test_ground_stations_in_real_tlogs(cli: Cli, real_captures: Path, name: str) -> None:
    path = real_captures / name
    msgs = read(path)
    gcs = {m.src[0] for m in msgs if m.name == "HEARTBEAT" and m.msg.type == MAV_TYPE_GCS}
    assert gcs, "every real tlog we hold was written by a ground station that sends HEARTBEATs"
    seqs: dict[tuple[int, int], list[int]] = defaultdict(list)
    for m in msgs:
        seqs[m.src].append(header(m.msg)[1])

    native = cli("stats", path, "--json")
    assert native == cli("stats", path, "--json", environ=PURE)  # both engines: stdout, stderr, status
    assert cli("audit", path) == cli("audit", path, environ=PURE)
    doc = cli.json("stats", path)
    links = {f"{lk['sysid']}/{lk['compid']}": lk for lk in doc["links"]}
    shared = {_link(f) for f in doc["findings"] if f["code"] == "seq-shared-counter"}
    explained = {_link(f): f for f in doc["findings"] if f["code"] == "seq-logged-in-part"}
    warned = {_link(f) for f in doc["findings"] if f["code"] == "seq-gap"}
    partial = 0
    for key, lk in links.items():
        is_gcs = lk["sysid"] in gcs
        assert lk["logged_in_part"] is is_gcs, key
        if not is_gcs:
            assert key not in explained, key
            continue
        partial += lk["lost"]
        assert key not in warned, key  # never a loss warning for a ground station's own frames in a tlog
        src = (lk["sysid"], lk["compid"])
        missing = _missing(seqs[src]) if src in seqs else 0
        if key in shared:  # numbers other ids on its counter used are not missing (seq-shared-counter)
            assert 0 < lk["lost"] <= missing, key
        else:
            assert lk["lost"] == missing, key
        if lk["lost"]:
            note = explained[key]
            assert note["severity"] == "note", key
            assert f"{lk['lost']} numbers missing" in note["message"] and "not link loss" in note["message"]
        else:
            assert key not in explained, key
    assert doc["totals"]["lost_logged_in_part"] == partial
    assert doc["totals"]["lost"] == sum(lk["lost"] for lk in links.values())

    status, out, _ = cli("stats", path, "--sparklines", "0")
    assert status == 0
    starred = [line for line in out.splitlines() if line.startswith("* ")]
    with_loss = [k for k, lk in links.items() if lk["logged_in_part"] and lk["lost"]]
    if with_loss:
        (line,) = starred
        assert line.startswith(f"* {', '.join(with_loss)}: ") and "not link loss" in " ".join(out.split())
        assert f"{doc['totals']['lost'] - partial} lost on the links ({partial} more" in " ".join(out.split())
    else:
        assert not starred


def test_a_built_tlog_and_pcap(cli: Cli, tmp_path: Path) -> None:
    """A vehicle (1/1, HEARTBEAT type quadrotor) and a ground station (255/190, type GCS) each lose 20
    frames in a row and 3 single ones, as written here: in a tlog the vehicle's 23 are link loss (seq-gap)
    and the ground station's 23 are explained; captured on the wire (UDP), both are link loss."""
    vehicle, station = flows.Sender(1, 1), flows.Sender(255, 190)
    entries: list[tuple[float, bytes]] = []
    datagrams = []
    for i in range(200):
        for s, gcs, (src, dst) in ((vehicle, False, (("10.0.0.2", 14550), ("10.0.0.1", 14550))),
                                   (station, True, (("10.0.0.1", 14550), ("10.0.0.2", 14550)))):
            frame = s.pack(flows.heartbeat(gcs=gcs))
            if 50 <= i < 70 or i in (100, 130, 160):
                continue  # lost: its sequence number was used
            entries.append((flows.T0 + i * 0.1, frame))
            datagrams.append((src, dst, frame))
    tlog = flows.write_tlog(tmp_path, entries)
    assert cli("stats", tlog, "--json") == cli("stats", tlog, "--json", environ=PURE)
    assert cli("stats", tlog) == cli("stats", tlog, environ=PURE)
    doc = cli.json("stats", tlog)
    links = {f"{lk['sysid']}/{lk['compid']}": lk for lk in doc["links"]}
    assert (links["1/1"]["lost"], links["1/1"]["logged_in_part"]) == (23, False)
    assert (links["255/190"]["lost"], links["255/190"]["logged_in_part"]) == (23, True)
    assert (doc["totals"]["lost"], doc["totals"]["lost_logged_in_part"]) == (46, 23)
    codes = {(f["code"], _link(f)) for f in doc["findings"]}
    assert codes == {("seq-gap", "1/1"), ("seq-logged-in-part", "255/190")}
    text = " ".join(cli("stats", tlog)[1].split())
    assert "* 255/190: ground station (HEARTBEAT type GCS) in a tlog" in text
    assert "23 lost on the links (23 more missing from ground stations' own frames" in text

    pcap = flows.write_udp_pcap(tmp_path / "flow.pcap", datagrams)
    assert cli("stats", pcap, "--json") == cli("stats", pcap, "--json", environ=PURE)
    doc = cli.json("stats", pcap)
    assert not any(lk["logged_in_part"] for lk in doc["links"]) and doc["totals"]["lost_logged_in_part"] == 0
    assert {(f["code"], _link(f)) for f in doc["findings"]} == {("seq-gap", "1/1"), ("seq-gap", "255/190")}
    assert "lost on the links" not in cli("stats", pcap)[1]
