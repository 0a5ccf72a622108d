#!/usr/bin/env python3
"""A hostile capture for `stats`: N HEARTBEATs (v2), each from a random one of the 65,536 senders with a
random sequence number, as a tlog (pymavlink packs the frames; seeded, so the same N gives the same file).

    benchmarks/hostile_senders.py N OUT.tlog

docs/performance.md ("`stats` on a capture that sprays senders") times `mavscope stats --json` on it.
"""

from __future__ import annotations

import random
import struct
import sys

from pymavlink.dialects.v20 import common as mavlink


def main(n: int, out: str) -> None:
    rnd = random.Random(7)
    mav = mavlink.MAVLink(None)
    hb = mavlink.MAVLink_heartbeat_message(2, 3, 0, 0, 4, 3)
    buf = bytearray()
    t0 = 1_700_000_000_000_000
    for i in range(n):
        mav.srcSystem, mav.srcComponent = rnd.randrange(1, 256), rnd.randrange(1, 256)
        mav.seq = rnd.randrange(256)
        buf += struct.pack(">Q", t0 + i * 1000) + hb.pack(mav)
    with open(out, "wb") as f:
        f.write(buf)


if __name__ == "__main__":
    main(int(sys.argv[1]), sys.argv[2])
