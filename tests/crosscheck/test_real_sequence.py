"""The Links table's loss, late and duplicate counts on real captures against an independent walk of
the sequence numbers (tests/support/seqwalk.py): the same story told by code that shares nothing with
mavscope's.

The sequence numbers come from every tlog entry that holds a frame header, read here by hand (8 bytes of
time, STX, then SEQ and the sender at the header's fixed offsets), so that frames pymavlink will not
decode still count: ArduSub's camera frames with a CRC computed before trimming, PX4's cut last frame.
A raw stream goes through pymavlink's own parser (the gomavlib vectors). px4_fw_mission_download_raw.bin
is left out: 14 of its frames (LINK_NODE_STATUS, CURRENT_EVENT_SEQUENCE) are unknown to pymavlink 2.4.50,
whose parser drops them; tests/crosscheck/test_real_captures.py checks that file's frames.
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import pytest

from tests.conftest import Cli
from tests.support.pymavlink_reader import read
from tests.support.seqwalk import walk

FILES = ["ap_plane_sitl_mission3types_ftp_mp_mavproxy.tlog", "ap_rover_mission_fence_rally_params.tlog",
         "ardusub_log_tools_small.tlog", "bluerobotics_mavlink_server_blueos_00025.tlog",
         "px4_2018_params_offboard.tlog", "px4flow_v1_encapsulated_data.tlog",
         "gomavlib_signed_testvectors_key4F_DERIVED.raw"]


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
    if name.endswith(".tlog"):
        for src, seq in _tlog_headers((real_captures / name).read_bytes()):
            seqs[src].append(seq)
    else:
        for m in read(real_captures / name):
            seqs[m.src].append(m.msg.get_seq())
    doc = cli.json("stats", real_captures / name)
    links = {(lk["sysid"], lk["compid"]): lk for lk in doc["links"]}
    for src, values in seqs.items():
        w = walk(values)
        lk = links[src]
        got = (lk["received"], lk["lost"], lk["reordered"], lk["duplicates"] + lk["unchanged_seq"])
        assert got == (w.frames, w.missing, w.late, w.same + w.behind), (src, w)
