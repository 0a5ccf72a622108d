"""The Links table's loss, late and duplicate counts on real captures against an independent walk of
the sequence numbers (tests/support/seqwalk.py): the same story told by code that shares nothing with
mavscope's.

The sequence numbers come from every tlog entry that holds a frame header, read here by hand (8 bytes of
time, STX, then SEQ and the sender at the header's fixed offsets), so that frames pymavlink will not
decode still count: ArduSub's camera frames with a CRC computed before trimming, PX4's cut last frame.
A raw stream goes through pymavlink's own parser (the gomavlib vectors). px4_fw_mission_download_raw.bin
is left out: 14 of its frames (LINK_NODE_STATUS, CURRENT_EVENT_SEQUENCE) are unknown to pymavlink 2.4.50,
whose parser drops them; tests/crosscheck/test_real_captures.py checks that file's frames.

Two tlogs hold ids that number their frames on one counter (SHARED): BlueOS's mavlink-server sends its own
HEARTBEAT as 1/194 and the ground station's as 255/240 (1/194 numbered 49, 255/240 50 and 51, 1/194 52...);
ArduSub's companion computer sends 1/194's HEARTBEAT and 1/220's GPS_INPUT. Each alone skips about half its
numbers or more (235 and 225; 1,009 and 263); walked as one counter, the group misses 26 and 0. Their loss is
that of the one counter, each missing number charged to the id whose frame revealed it (`walk_merged`).

Pcaps of UDP (the real ones, and the bundled captures/px4_sitl_sll2.pcapng, where one ground station
talks to two vehicles over two links) are read by scapy, each datagram through pymavlink's parser, and
walked per channel: MAVLink keeps one sequence counter per channel, a channel here being the datagram's
source and destination address and port.
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import pytest

from tests.conftest import Cli
from tests.support.pymavlink_reader import read
from tests.support.seqwalk import walk, walk_channels, walk_merged

PCAPS = ["ap_sitl_attack1_signed_knownkey.pcap", "ipal_transcriber_MAVLink.pcap"]
SLL2 = Path(__file__).resolve().parents[2] / "captures" / "px4_sitl_sll2.pcapng"
FILES = ["ap_plane_sitl_mission3types_ftp_mp_mavproxy.tlog", "ap_rover_mission_fence_rally_params.tlog",
         "ardusub_log_tools_small.tlog", "bluerobotics_mavlink_server_blueos_00025.tlog",
         "px4_2018_params_offboard.tlog", "px4flow_v1_encapsulated_data.tlog",
         "gomavlib_signed_testvectors_key4F_DERIVED.raw"]
SHARED = {"ardusub_log_tools_small.tlog": {(1, 194), (1, 220)},
          "bluerobotics_mavlink_server_blueos_00025.tlog": {(1, 194), (255, 240)}}


def _tlog_headers(data: bytes) -> list[tuple[tuple[int, int], int]]:
    """(sender, seq) of every entry whose bytes start with a frame header, entries delimited by the
    frame length the header gives, or skipped one byte at a time (console text) where no header is."""
    out = []
    o = 0
    while o + 8 + 6 <= len(data):
        stx = data[o + 8]
        if stx == 0xFD and o + 8 + 10 <= len(data):
            out.append(((data[o + 8 + 5], data[o + 8 + 6]), data[o + 8 + 4]))
            o += 8 + 12 + data[o + 9] + (13 if data[o + 10] & 1 else 0)
        elif stx == 0xFE:
            out.append(((data[o + 8 + 3], data[o + 8 + 4]), data[o + 8 + 2]))
            o += 8 + 8 + data[o + 9]
        else:
            o += 9  # a one-byte text entry
    return out


@pytest.mark.parametrize("name", FILES)
def test_links_agree_with_an_independent_sequence_walk(cli: Cli, real_captures: Path, name: str) -> None:
    seqs: dict[tuple[int, int], list[int]] = defaultdict(list)
    group = SHARED.get(name, set())
    merged = []  # the shared counter's frames, in capture order
    if name.endswith(".tlog"):
        for src, seq in _tlog_headers((real_captures / name).read_bytes()):
            seqs[src].append(seq)
            if src in group:
                merged.append((src, seq))
    else:
        for m in read(real_captures / name):
            seqs[m.src].append(m.msg.get_seq())
    charged = walk_merged(merged)
    if group:  # one counter: the group misses far fewer numbers than its ids alone
        assert sum(charged.values()) * 5 < sum(walk(seqs[src]).missing for src in group)
    doc = cli.json("stats", real_captures / name)
    links = {(lk["sysid"], lk["compid"]): lk for lk in doc["links"]}
    for src, values in seqs.items():
        w = walk(values)
        lk = links[src]
        got = (lk["received"], lk["lost"], lk["reordered"], lk["duplicates"] + lk["unchanged_seq"])
        assert got == (w.frames, charged.get(src, w.missing), w.late, w.same + w.behind), (src, w)


def _udp_channels(path: Path) -> dict[tuple[int, int], dict[tuple[str, str], list[int]]]:
    """sender -> (source, destination) of its datagrams -> its sequence numbers, read by scapy and pymavlink."""
    from pymavlink.dialects.v20 import all as mavlink
    from scapy.layers.inet import IP, UDP
    from scapy.layers.inet6 import IPv6
    from scapy.utils import rdpcap

    out: dict[tuple[int, int], dict[tuple[str, str], list[int]]] = defaultdict(lambda: defaultdict(list))
    for pkt in rdpcap(str(path)):
        if UDP not in pkt:
            continue
        ip = pkt[IP] if IP in pkt else pkt[IPv6]
        chan = (f"{ip.src} {pkt[UDP].sport}", f"{ip.dst} {pkt[UDP].dport}")
        mav = mavlink.MAVLink(None)
        mav.robust_parsing = True
        for m in mav.parse_buffer(bytes(pkt[UDP].payload)) or []:
            if not isinstance(m, mavlink.MAVLink_bad_data):
                out[(m.get_srcSystem(), m.get_srcComponent())][chan].append(m.get_seq())
    return out


def _check_links(cli: Cli, path: Path) -> dict[tuple[int, int], dict[tuple[str, str], list[int]]]:
    channels = _udp_channels(path)
    doc = cli.json("stats", path)
    links = {(lk["sysid"], lk["compid"]): lk for lk in doc["links"]}
    assert set(links) == set(channels)
    for src, chans in channels.items():
        w = walk_channels(chans.values())
        lk = links[src]
        got = (lk["received"], lk["lost"], lk["reordered"], lk["duplicates"] + lk["unchanged_seq"])
        assert got == (w.frames, w.missing, w.late, w.same + w.behind), (src, w)
    return channels


@pytest.mark.parametrize("name", PCAPS)
def test_udp_links_agree_with_a_walk_per_channel(cli: Cli, real_captures: Path, name: str) -> None:
    _check_links(cli, real_captures / name)


def test_one_gcs_on_two_links_repeats_no_number(cli: Cli) -> None:
    """captures/px4_sitl_sll2.pcapng: 255/190 sends its HEARTBEAT to 2/1 over IPv4 and to 1/1 over IPv6, each
    link numbered from 0 (10 each). Walked as one counter, every number comes twice (10 "duplicates"); per
    channel, none. Neither the Links table nor the findings may call them duplicates."""
    channels = _check_links(cli, SLL2)
    gcs = channels[(255, 190)]
    assert len(gcs) == 2 and all(v == list(range(10)) for v in gcs.values())  # one counter: each number twice
    findings = cli.json("stats", SLL2)["findings"]
    assert [f for f in findings if f["code"].startswith("seq-")] == []
