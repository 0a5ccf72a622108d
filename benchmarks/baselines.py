#!/usr/bin/env python3
"""The pymavlink baselines the read benchmark compares with, run as their own processes:

    benchmarks/baselines.py struct FILE   # mmap + struct pcap loop, MAVLink.parse_buffer, json.dumps(to_dict())
    benchmarks/baselines.py scapy FILE    # scapy's PcapReader + pymavlink: the typical script

Each writes one JSON line per frame to stdout and `frames=N` to stderr.
"""

from __future__ import annotations

import json
import struct
import sys


def baseline_struct(path: str) -> int:
    """A plain, fast pcap loop: mmap + struct record headers, Ethernet/IPv4/UDP checked by hand."""
    import mmap

    from pymavlink.dialects.v20 import all as mavlink

    mav = mavlink.MAVLink(None)
    mav.robust_parsing = True
    parse, dumps, write = mav.parse_buffer, json.dumps, sys.stdout.write
    n = 0
    with open(path, "rb") as fh:
        buf = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)
        size = len(buf)
        unpack = struct.Struct("<IIII").unpack_from
        pos = 24
        while pos + 16 <= size:
            _, _, incl, _ = unpack(buf, pos)
            pkt = buf[pos + 16 : pos + 16 + incl]
            pos += 16 + incl
            if pkt[12:14] != b"\x08\x00" or pkt[23] != 17:
                continue
            msgs = parse(pkt[14 + (pkt[14] & 15) * 4 + 8 :])
            if msgs:
                for m in msgs:
                    if m._type != "BAD_DATA":
                        n += 1
                        write(dumps(m.to_dict()) + "\n")
    return n


def baseline_scapy(path: str) -> int:
    """The typical script: scapy's PcapReader (full dissection) + pymavlink."""
    from pymavlink.dialects.v20 import all as mavlink
    from scapy.layers.inet import UDP
    from scapy.utils import PcapReader

    mav = mavlink.MAVLink(None)
    mav.robust_parsing = True
    n = 0
    write = sys.stdout.write
    with PcapReader(path) as pr:
        for pkt in pr:
            if UDP in pkt:
                msgs = mav.parse_buffer(bytes(pkt[UDP].payload))
                if msgs:
                    for m in msgs:
                        if m._type != "BAD_DATA":
                            n += 1
                            write(json.dumps(m.to_dict()) + "\n")
    return n


def main() -> int:
    mode, path = sys.argv[1], sys.argv[2]
    n = (baseline_struct if mode == "struct" else baseline_scapy)(path)
    sys.stdout.flush()
    print(f"frames={n}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
