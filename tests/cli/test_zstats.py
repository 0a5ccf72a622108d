"""`read -z`: MAVLink's own statistics and the expert's, as `stats` and the frames' notes give them.

`-z mavlink,links` and `-z mavlink,msgs` must say what `stats --json` says for every link and message (the
same analyses, one implementation); `-z expert` counts each note code as the frames' notes in
`read -T jsonl` do (counted here from the JSON), and lists `stats`' findings. `-q` leaves only the
statistics; without it the frames come first. A wrong spec is refused before the capture is read.
"""

from __future__ import annotations

import json
import re
from collections import Counter

from tests.conftest import CAPTURES, Cli


def test_links_and_messages_as_stats_says(cli: Cli) -> None:
    path = str(CAPTURES / "stats_loss.pcap")
    doc = json.loads(cli("stats", path, "--json").out)
    out = cli("read", path, "-q", "-z", "mavlink,links", "-z", "mavlink,msgs").out
    links = {(int(m.group(1)), int(m.group(2))): (int(m.group(3)), int(m.group(4)))
             for m in re.finditer(r"^ *(\d+)/(\d+) +(\d+) +(\d+)\*? +[\d.-]+ +\d+ +\d+$", out, re.M)}
    assert links == {(lk["sysid"], lk["compid"]): (lk["received"], lk["lost"]) for lk in doc["links"]} != {}
    msgs = {(int(m.group(1)), int(m.group(2)), m.group(3)): int(m.group(4))
            for m in re.finditer(r"^ *(\d+)/(\d+) +([A-Z_0-9]+) +(\d+) +\S+ +\d+$", out, re.M)}
    assert msgs == {(m["sysid"], m["compid"], m["msgname"]): m["count"] for m in doc["messages"]}


def test_expert_counts_the_frames_notes(cli: Cli) -> None:
    path = str(CAPTURES / "damaged.pcap")
    want = Counter(n["code"] for line in cli("read", path, "-T", "jsonl").out.splitlines()
                   for n in json.loads(line)["notes"])
    out = cli("read", path, "-q", "-z", "expert").out
    got: Counter[str] = Counter()
    for m in re.finditer(r"^ +(\d+)  (\S+) ", out, re.M):
        got[m.group(2)] += int(m.group(1))
    assert got == want and want


def test_q_leaves_only_the_statistics_and_a_bad_spec_is_refused(cli: Cli) -> None:
    path = str(CAPTURES / "px4_sitl_udp.pcap")
    quiet = cli("read", path, "-q", "-z", "conv,udp")
    loud = cli("read", path, "-z", "conv,udp", "-c", "3")
    assert quiet.out.startswith("=" * 80) and "HEARTBEAT" not in quiet.out
    assert loud.out.splitlines()[0].lstrip().startswith("1 ") and "UDP Conversations" in loud.out
    assert "1371" in loud.out  # -c 3 shows 3 frames; the statistics count all 1,371
    for spec in ("conv,ipx", "io,stat,0", "io,stat,x", "io,stat,1,HEARTBEAT.typ == 2"):
        bad = cli("read", path, "-q", "-z", spec)
        assert bad.status == 2 and bad.out == "", spec
