#!/usr/bin/env python3
"""A WPA2 monitor-mode capture for `stats --wifi-key`: a 4-way handshake, then N CCMP-encrypted QoS data
frames from the GCS station to its access point, each a UDP datagram holding one MAVLink HEARTBEAT
(tests/support/wpa.py builds the frames from IEEE 802.11-2016; the same N gives the same file).

    benchmarks/wifi_wpa2.py N OUT.pcap

docs/performance.md ("Decrypting WPA2") times `mavscope stats --json --wifi-key ...` on it; the key is
`wpa-pwd:drone-pass-2024:ArduPilotNet`.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from scapy.utils import PcapWriter  # noqa: E402

from tests.support import wpa as w  # noqa: E402


def main(n: int, out: str) -> None:
    pw = PcapWriter(out, linktype=127, sync=False)
    for p in w.handshake():
        pw.write(p)
    for i in range(n):
        pw.write(w.ccmp_frame(w.AP, w.STA, i % 4096, i + 1, w.mavlink_packet(255, i % 256)))
    pw.close()


if __name__ == "__main__":
    main(int(sys.argv[1]), sys.argv[2])
